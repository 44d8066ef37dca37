"""Boards: the one seam between the flight core and the world (sim, linux, rp2)."""
