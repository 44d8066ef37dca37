"""Native-code twins (`@micropython.viper`) of the flight pass's stages, MicroPython only.

Not portable code: viper compiles to the target's machine code, so mpy-cross needs its `-march`
(`hoverfly flash` passes the chip's) and CPython cannot import these modules. The portable module that
uses one imports it on MicroPython only, inside try/except, and keeps its own Python code as the
reference and the fallback; the twin tests check both give the same bits.

Every module here but addr.py is generated from its Python by hoverfly.fastgen (docs/fastpass.md;
fastgen.STAGES names them) and is not in git (.gitignore). addr.py holds what they share: `bind` and the
encode's `LOG2` table.
"""
