"""DICOM loading: file discovery, slice geometry, pixel decoding and series assembly."""
