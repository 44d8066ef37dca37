"""Ground station (CPython)."""
