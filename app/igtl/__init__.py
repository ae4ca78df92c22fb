"""OpenIGTLink out: a rehearsal's drill, implant and forces streamed live to 3D Slicer.

- :mod:`ctdrill.app.igtl.frames`: the ``--igtl HOST:PORT`` target, the poses (LPS inside,
  RAS on the wire) and the ``Forces`` document; pure functions.
- :mod:`ctdrill.app.igtl.stream`: :class:`~ctdrill.app.igtl.stream.IgtlStream`, the sender
  thread behind a latest-value slot, observing a session's telemetry blocks; its report is
  ``summary.json`` ``igtl``.

docs/slicer.md says how to watch a rehearsal in Slicer.
"""
