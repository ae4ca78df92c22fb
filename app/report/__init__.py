"""``ctdrill report``: one PDF of a planned case, drawn off screen (docs/report.md).

The numbers are the export's (:func:`ctdrill.engine.case.prepare_case`,
:func:`ctdrill.engine.summarize.job_summary`): the report draws them, it never computes them
another way. Modules: :mod:`.layout` (pages of wrapped text and tables), :mod:`.summary` (the
summary table and every trajectory's lines and warnings), :mod:`.curves` (force, HU and clearance
against depth), :mod:`.views` (panoramic, cross-sections, 3D), :mod:`.build` (the whole
document, written atomically).
"""
