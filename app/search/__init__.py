"""Trajectory search: candidate axes around a plan, scored and ranked (``ctdrill suggest``).

The candidates are evaluated in one batch by :func:`ctdrill.engine.batch.evaluate_batch`
(the engine's path rules, the same answers as :func:`ctdrill.engine.path.plan_path`).
"""
