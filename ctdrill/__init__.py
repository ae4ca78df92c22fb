"""ctdrill: rehearse a dental-implant osteotomy on the patient's own CT.

The import package ``ctdrill`` gathers the repository's top-level folders, each a room of its
own (``docs/architecture.md``):

- ``ctdrill.imaging`` (``imaging/``): DICOM series -> HU volume, sampling, plans, landmarks,
  clearance, the phantom and its writer.
- ``ctdrill.model`` (``model/``): force law, profiles, calibration sets and fitting.
- ``ctdrill.haptics`` (``haptics/``): device protocol, renderer, simulator, serial link, sessions.
- ``ctdrill.engine`` (``engine/``): one CT combined with the force model along trajectories: the
  path rules, the stop, drill sequences, the plan's verdict and the summaries every output reads.
- ``ctdrill.app`` (``app/``): CLI, headless export, rehearsal and the Qt GUI.
- ``ctdrill.assets`` (``assets/``): package data (calibration sets, the demo case), read through
  :func:`ctdrill.resources.asset`.

``pyproject.toml`` maps those folders into this package (``package-dir``), in an editable install
and in the wheel alike. Importing ``ctdrill`` imports none of them.
"""

__version__ = "0.1.0"
