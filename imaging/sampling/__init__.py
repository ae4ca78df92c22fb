"""Sampling the CT: the drill lip rings and what the path crosses."""
