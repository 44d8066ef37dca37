"""The simulator's flash: the parameter image as a file on the host (`hoverfly sim --storage PATH`).

Takes a path (or None: no storage file, nothing kept) and the image bytes core/config/storage.py
builds; gives them back at the next boot. Used by the sim board's `load_storage` and
`save_storage`. A module of its own so the board does not import the TCP server (sim/server.py),
which imports the runner, which imports the board: that was an import circle.
"""

import os


def load_storage_file(path):
    """The stored image, or None when there is no file (a fresh board: defaults)."""
    if path is None or not os.path.exists(path):
        return None
    with open(path, "rb") as fh:
        return fh.read()


def save_storage_file(path, image):
    """Write the image in place: bytes that did not change are rewritten with their old value, so a
    write cut anywhere leaves the untouched slot whole (as flash would)."""
    if path is None:
        return False
    mode = "r+b" if os.path.exists(path) else "wb"
    with open(path, mode) as fh:
        fh.seek(0)
        fh.write(image)
        fh.truncate(len(image))
        fh.flush()
        os.fsync(fh.fileno())
    return True
