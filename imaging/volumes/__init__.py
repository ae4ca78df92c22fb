"""Volume files (NIfTI, NRRD, MetaImage): CT volumes and label maps, bounded and exact.

One owner for the geometry and size rules of every file format that carries its own grid
(:mod:`.grid`, :mod:`.bounded`), the readers (:mod:`.nifti_file`, :mod:`.nrrd_file`,
:mod:`.metaimage`), the content sniffer (:mod:`.sniff`) and the CT loader (:mod:`.load`:
``load_ct`` takes a DICOM folder or file, a NIfTI, a NRRD or a MetaImage file alike).
"""
