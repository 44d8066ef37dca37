"""What the MicroPython VM spends on the pass's glue: a call and an attribute look-up, in instructions.

Run: `.venv/bin/python bench/call_cost.py` (needs `valgrind` and the MicroPython VM, as bench/stage_instructions.py;
about half a minute). Each kind runs in a loop of its own inside `map`'s iterator, counted by callgrind as
bench/stage_instructions.py counts a stage, at two lengths: the difference over the extra iterations, less an
empty loop's, is one of it. The kinds: a bytecode method call (`obj.m(a, b, c)`: the method's look-up on the
instance and its class, the frame), a viper method call the same way, a viper function held in a local, and an
attribute load from an instance (`obj.x`). Prints one JSON object: {kind: instructions}. These are what the
pass's bytecode stages pay around the viper kernels (docs/pico.md, "What a pass costs").
"""

import sys

RUNS = (2000, 4000)
KINDS = ("empty", "bytecode_method_call", "viper_method_call", "viper_function_call", "attribute_load")


def _child(kind, n):
    import micropython

    class Stage:
        def __init__(self):
            self.x = 1

        def m(self, a, b, c):
            pass

        @micropython.viper
        def v(self, a, b, c):
            pass

    @micropython.viper
    def vf(a, b, c):
        pass

    def empty(obj, n):
        for _ in range(n):
            pass

    def bytecode_method_call(obj, n):
        for _ in range(n):
            obj.m(1, 2, 3)

    def viper_method_call(obj, n):
        for _ in range(n):
            obj.v(1, 2, 3)

    def viper_function_call(obj, n):
        f = vf
        for _ in range(n):
            f(1, 2, 3)

    def attribute_load(obj, n):
        for _ in range(n):
            obj.x  # noqa: B018 (the look-up is what is counted)

    run = {"empty": empty, "bytecode_method_call": bytecode_method_call, "viper_method_call": viper_method_call,
           "viper_function_call": viper_function_call, "attribute_load": attribute_load}[kind]
    obj = Stage()
    for _ in map(lambda k: run(obj, k), [n]):
        pass


def main():
    import json

    from stage_instructions import child_counts

    args = [(k, str(n)) for k in KINDS for n in RUNS]
    counts, error = child_counts(__file__, args)
    if error:
        print(json.dumps({"error": error}))
        return 1
    per = {}
    for i, kind in enumerate(KINDS):
        per[kind] = (counts[2 * i + 1] - counts[2 * i]) / (RUNS[1] - RUNS[0])
    print(json.dumps({k: round(per[k] - per["empty"]) for k in KINDS if k != "empty"}))
    return 0


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "--child":
        _child(sys.argv[2], int(sys.argv[3]))
    else:
        sys.exit(main())
