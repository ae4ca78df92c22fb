"""``ctdrill batch``: export every row of a manifest (a cohort), on this machine's cores or on a
Dask cluster, with a status table and resume (``docs/batch.md``).

- :mod:`.manifest`: the manifest (``dicom, plan`` per row, paths relative to it; ids; paths
  as the outputs show them);
- :mod:`.task`: one row's task and its outcome, the function a worker runs, and the input
  fingerprint and sealed marker that make a row's output "complete";
- :mod:`.inputs`: the identities of what a row read and wrote;
- :mod:`.workers`: the in-process and process-pool runners, Ctrl-C, workers that die with
  the batch;
- :mod:`.cluster`: dask.distributed, with a bounded connection;
- :mod:`.run`: resume, the status table and the cohort's table.
"""
