"""No class of the portable code carries a property or an attribute hook.

On MicroPython a class with a property (or a descriptor, or __getattr__/__setattr__/__delattr__),
or a subclass of one, is marked as having special accessors, and then every attribute store on its
instances looks the name up in the class first: 0.21-0.28 µs a store against 0.07 on the unix VM
(bench/attr_store.py, docs/pico.md). Five such properties on classes the pass stores into (the IMU drivers' base, the
DShot command queue, the failsafe, the autopilot, the built-in test) cost 15.6 k of the pass's
268.6 k instructions (bench/core_instructions.py). So the portable packages use methods instead,
and this keeps it so.
"""

import importlib
import inspect
import pathlib

import hoverfly

ROOT = pathlib.Path(hoverfly.__file__).parent
HOOKS = ("__getattr__", "__setattr__", "__delattr__", "__get__", "__set__", "__delete__")


def _portable_modules():
    names = ["hoverfly.compat"]
    for pkg in ("core", "protocols", "drivers"):
        for path in sorted((ROOT / pkg).glob("*.py")):
            if path.name != "__init__.py":
                names.append("hoverfly.%s.%s" % (pkg, path.stem))
    return names


def test_no_portable_class_has_a_property_or_an_attribute_hook():
    offenders = []
    classes = 0
    for name in _portable_modules():
        mod = importlib.import_module(name)
        for cname, cls in inspect.getmembers(mod, inspect.isclass):
            if cls.__module__ != name:
                continue
            classes += 1
            for klass in cls.__mro__[:-1]:  # object's own slots are not the class's
                for attr, value in vars(klass).items():
                    if attr in ("__dict__", "__weakref__"):  # CPython's own slots on every class
                        continue
                    if isinstance(value, property) or attr in HOOKS or hasattr(type(value), "__set__"):
                        offenders.append("%s.%s.%s" % (name, cname, attr))
    assert classes > 60, classes  # the scan found the portable classes
    assert not offenders, offenders
