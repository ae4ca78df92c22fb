"""Plans, landmarks and safety: the trajectory, the anatomy to protect and the clearance."""
