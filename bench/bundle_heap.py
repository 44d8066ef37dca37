"""How much heap the flash bundle needs on a 32-bit MicroPython, as an RP2040/RP2350 would load it.

Builds the all-bytecode bundle (`hoverfly flash --bytecode`, cli_flash.build) for the 32-bit unix port
(chip unix-x86), then runs bench/core_loop.py from it (the armed flight, 2000 passes, collections included)
under `micropython-i686` at heap sizes from 128 KB up in 32 KB steps, and reports the smallest that runs.
An RP2040's MicroPython heap is about 190 KB, an RP2350's about 400 KB (docs/pico.md): a bundle that needs more
than the board has must be frozen into the firmware, where code and constants stay in flash.

Run: `.venv/bin/python bench/bundle_heap.py` (the VM from HOVERFLY_MP32, else ../shared/tools/micropython-i686).
Prints one JSON object: {chip, bundle_bytes, min_heap_kb, us_per_pass, bytes_per_pass} (min_heap_kb null if
nothing up to 1 MB ran).
"""

import json
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(ROOT, "src"))

from hoverfly.cli_flash import build  # noqa: E402

CHIP = "unix-x86"
STEP_KB = 32


def _vm():
    exe = os.environ.get("HOVERFLY_MP32") or os.path.join(os.path.dirname(ROOT), "shared", "tools", "micropython-i686")
    if not os.path.exists(exe):
        sys.exit("bundle_heap: no 32-bit MicroPython at %s (set HOVERFLY_MP32)" % exe)
    return exe


def main():
    exe = _vm()
    with tempfile.TemporaryDirectory() as out:
        files = build(out, CHIP, native=())
        size = sum(os.path.getsize(f) for f in files)
        env = dict(os.environ, MICROPYPATH="%s:%s" % (os.path.join(out, "lib"), HERE))
        found = None
        for kb in range(128, 1024 + STEP_KB, STEP_KB):
            res = subprocess.run([exe, "-X", "heapsize=%dk" % kb, os.path.join(HERE, "core_loop.py")],
                                 capture_output=True, text=True, env=env, timeout=600)
            if res.returncode == 0:
                found = (kb, json.loads(res.stdout.strip().splitlines()[-1]))
                break
    print(json.dumps({"chip": CHIP, "bundle_bytes": size,
                      "min_heap_kb": found[0] if found else None,
                      "us_per_pass": found[1]["us_per_pass"] if found else None,
                      "bytes_per_pass": found[1]["bytes_per_pass"] if found else None}))


if __name__ == "__main__":
    main()
