"""The synthetic mandible phantom and the DICOM writer that stores it."""
