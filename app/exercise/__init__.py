"""Exercises that train the feel for bone (docs/exercises.md).

:mod:`ctdrill.app.exercise.seal` (the sealed answer key of a blind trial),
:mod:`ctdrill.app.exercise.trials` (a trial's card, found next to its plan; the blind summary),
:mod:`ctdrill.app.exercise.bone_quality` (``ctdrill exercise bone-quality``: blind trials of
Misch class D1-D4), :mod:`ctdrill.app.exercise.aids` (the stop-yourself exercise's aid levels),
:mod:`ctdrill.app.exercise.blind` (what every command may do with a blind trial).
"""
