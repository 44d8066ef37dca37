"""Who flies and with what set point: the commander, the companion computer's autopilot, the props-off motor test."""
