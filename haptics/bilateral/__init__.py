"""The paper's slave robot under bilateral control with the master, cutting a CT (docs/teleop.md).

* :mod:`.params`: the slave (Table 4), the four-channel gains, the channel, the hand;
* :mod:`.channel`: a link with delay, jitter and loss, seeded;
* :mod:`.environment`: the cutting environment of the slave (the model's lip-integrated force
  on a yielding front, unilateral, with the vibration);
* :mod:`.estimator`: the CT number from the slave's force (Eq. 25 reconstructed, the force gain
  estimated online) and the automatic stop from force alone;
* :mod:`.loop`: the 10 kHz loop of master, slave, channel and hand;
* :mod:`.metrics`: transparency, passivity, estimation and stop figures of one run.

Imports :mod:`ctdrill.model` and the master's plant only; plain floats in the loop.
"""
