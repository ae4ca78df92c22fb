"""Package data of ctdrill (calibration sets, implant library, the demo case): read through
:func:`ctdrill.resources.asset`, never imported for code."""
