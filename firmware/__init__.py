"""The device firmware's C sources (package data): see firmware/README.md.

Built for the host by :mod:`ctdrill.haptics.ccore` (``ctdrill emulate --core c``) and for a
Cortex-M4F by ``make firmware``. No Python here.
"""
