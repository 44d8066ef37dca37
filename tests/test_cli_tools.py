"""The terminal explains itself: the firmware bridge started from a user's folder, help that lists names,
scenario files checked key by key, "did you mean" for a misspelt name, the fly summary a pilot reads.

Given what a new user types (from the folder they cloned into, a typo, a bare `save`), when the CLI
runs, then it does what was asked or says in one line what to do instead.
"""

import os
import subprocess
import sys

import pytest

from test_micropython import MICROPYTHON

HOVERFLY = os.path.join(os.path.dirname(sys.executable), "hoverfly")
needs_mp = pytest.mark.skipif(MICROPYTHON is None, reason="micropython not installed")


def _user_folder(tmp_path):
    """A folder like the one a user cloned into: it holds a hoverfly/ folder that is not the package."""
    folder = tmp_path / "clone"
    (folder / "hoverfly").mkdir(parents=True)
    (folder / "hoverfly" / "__init__.py").write_text("raise ImportError('the user folder was imported')\n")
    return folder


@needs_mp
def test_fly_on_the_micropython_firmware_from_a_folder_holding_a_hoverfly_folder(tmp_path):
    folder = _user_folder(tmp_path)
    r = subprocess.run([HOVERFLY, "fly", "--scenario", "hover", "--duration", "2", "--firmware", "micropython",
                        "--micropython", MICROPYTHON], cwd=folder, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert "user folder" not in r.stderr and "no crash" in r.stdout


@needs_mp
def test_fly_from_a_flash_bundle_from_a_folder_holding_a_hoverfly_folder(tmp_path, unix_bundle):
    folder = _user_folder(tmp_path)
    r = subprocess.run([HOVERFLY, "fly", "--scenario", "hover", "--duration", "2", "--firmware", "micropython",
                        "--micropython", MICROPYTHON, "--bundle", str(unix_bundle)], cwd=folder,
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert "user folder" not in r.stderr and "no crash" in r.stdout
