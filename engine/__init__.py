"""ctdrill engine: one CT combined with the force model along drill trajectories.

Below ``app`` and above ``imaging`` and ``model`` (it imports those two only; only ``app``
imports it): the path rules (depth grid, refusals, volume edge, gaps, clearance, safe depth,
stop) written once for a batch of trajectories, the single trajectory as its one-row case,
drill sequences, and the case an export computes (summary, force series, band). ``app`` keeps
the interfaces: the command line, the files, the window.
"""
