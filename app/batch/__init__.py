"""``ctdrill batch``: export every row of a manifest (a cohort), on this machine's cores or on a
Dask cluster, with a status table and resume (``docs/batch.md``).

- :mod:`.manifest`: the manifest (``dicom, plan`` per row, paths relative to it);
- :mod:`.task`: one row's task and its outcome, the function a worker runs, and the input
  fingerprint that makes a row's output "complete";
- :mod:`.run`: the runners (in-process, a process pool, dask.distributed), resume, the
  status table and the cohort's table.
"""
