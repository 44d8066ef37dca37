import os
import sys

# The suite runs the .py files: a simulated flight would otherwise run on the compiled twins `./dev` builds
# (hoverfly/native.py), which tests/test_native.py holds bit-identical to them. Set before hoverfly is imported.
os.environ["HOVERFLY_NATIVE"] = "0"

HERE = os.path.dirname(__file__)
sys.path.insert(0, os.path.join(HERE, "portable"))
sys.path.insert(0, HERE)

import pytest  # noqa: E402

from hoverfly.fastgen import generate_all  # noqa: E402

# The viper stages the MicroPython VMs import from src/ are generated from the fixed-point Python (never
# committed, docs/fastpass.md): written here when their source changed.
generate_all()


@pytest.fixture(scope="session")
def unix_bundle(tmp_path_factory):
    """`hoverfly flash --out DIR --chip unix-x64`: the board's bundle (NATIVE_MODULES as machine code) built for the
    MicroPython VM here; the folder, or a skip without mpy-cross."""
    from hoverfly.cli_flash import build
    from test_micropython import MPY_CROSS

    if MPY_CROSS is None:
        pytest.skip("mpy-cross not installed")
    out = tmp_path_factory.mktemp("unix-bundle")
    build(out, "unix-x64", MPY_CROSS)
    return out
