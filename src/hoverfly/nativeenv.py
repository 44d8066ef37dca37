"""CPython start-up hook of hoverfly/native.py: with HOVERFLY_NATIVE set (not 0), the finder of the compiled twins
is installed before any simulator module loads. hoverfly/__init__.py imports this on CPython only; native.py
itself (hashing, building, its command line: python -m hoverfly.native) loads only when asked for."""

import os

if os.environ.get("HOVERFLY_NATIVE", "0") not in ("", "0"):
    from hoverfly import native

    native.install()
