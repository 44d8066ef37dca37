"""The parameter table and its storage."""
