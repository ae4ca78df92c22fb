"""A class of trainees: the class file, grades, confusion matrices and the dashboard.

:mod:`ctdrill.app.classroom.class_file` (``ctdrill-class/1``: the roster and the exercises),
:mod:`ctdrill.app.classroom.grades` (which sessions are whose attempts at which exercise, the
grades and the confusion matrices, pure functions of the record's rows),
:mod:`ctdrill.app.classroom.dashboard` (the figure), :mod:`ctdrill.app.classroom.report`
(``ctdrill class report``). docs/exercises.md.
"""
