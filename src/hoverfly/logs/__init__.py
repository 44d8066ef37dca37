"""Flight-log tools (CPython): readers, reports, plots, replay."""
