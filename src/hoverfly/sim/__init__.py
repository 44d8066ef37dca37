"""The simulator (CPython): physics, airframes, sensor models, scenarios and pilots."""
