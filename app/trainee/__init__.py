"""Learning from rehearsals: exam mode, the session's assessment, the trainee record.

:mod:`ctdrill.app.trainee.exam` (the table without the margin's wall, what a session is measured
against, the plan's hash), :mod:`ctdrill.app.trainee.session_files` (a session folder: its
assessment, its replay trace, its hash), :mod:`ctdrill.app.trainee.record` (the SQLite trainee
record), :mod:`ctdrill.app.trainee.curve` (learning curve and percentiles),
:mod:`ctdrill.app.trainee.words` (the assessment in plain words). The assessment itself and its
score are :mod:`ctdrill.haptics.assessment`. docs/rehearse.md.
"""
