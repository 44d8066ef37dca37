"""No class of the portable code carries a property or an attribute hook.

On MicroPython a class with a property (or a descriptor, or __getattr__/__setattr__/__delattr__),
or a subclass of one, is marked as having special accessors, and then every attribute store on its
instances looks the name up in the class first: two to three times the cost of a store on a plain class
(`MICROPYPATH=src .venv/bin/micropython bench/attr_store.py`; docs/pico.md). The pass stores into dozens of
attributes, so the portable packages use methods instead, and this keeps it so.
"""

import ast
import importlib
import inspect
import pathlib

import hoverfly

ROOT = pathlib.Path(hoverfly.__file__).parent
HOOKS = ("__getattr__", "__setattr__", "__delattr__", "__get__", "__set__", "__delete__")
PORTABLE = ("core", "protocols", "drivers")  # with compat.py: the code MicroPython runs as it is
BOARD = ("boards/rp2",)  # MicroPython only (it imports `machine`): read as source, not imported
WHY = ("on MicroPython a class with a property, a descriptor or an attribute hook (or a subclass of one) makes "
       "every attribute store on its instances look the name up in the class first, about 3x the cost of a plain "
       "store (bench/attr_store.py); the pass stores into its stages' attributes thousands of times a second. "
       "Use a method (get_x()/set_x()) or a plain attribute instead")


def _portable_modules():
    names = ["hoverfly.compat"]
    for pkg in PORTABLE:
        for path in sorted((ROOT / pkg).rglob("*.py")):  # subpackages too
            parts = path.relative_to(ROOT).with_suffix("").parts
            if parts[-1] != "__init__":
                names.append("hoverfly." + ".".join(parts))
    return names


def class_offenders(mod):
    """["module.Class.attr"] for each property, descriptor or attribute hook of the module's own classes,
    inherited ones included, and the number of classes looked at."""
    offenders = []
    classes = 0
    for cname, cls in inspect.getmembers(mod, inspect.isclass):
        if cls.__module__ != mod.__name__:
            continue
        classes += 1
        for klass in cls.__mro__[:-1]:  # object's own slots are not the class's
            for attr, value in vars(klass).items():
                if attr in ("__dict__", "__weakref__"):  # CPython's own slots on every class
                    continue
                if isinstance(value, property) or attr in HOOKS or hasattr(type(value), "__set__"):
                    offenders.append("%s.%s.%s" % (mod.__name__, cname, attr))
    return offenders, classes


def source_offenders(text, label):
    """The same read from source, for code CPython cannot import and for classes made inside a function:
    ["label:line what"] for each property decorator or call, accessor decorator, hook method or __slots__."""
    found = []
    for node in ast.walk(ast.parse(text, label)):
        if isinstance(node, ast.ClassDef):
            for item in node.body:
                if isinstance(item, ast.FunctionDef) and item.name in HOOKS:
                    found.append("%s:%d %s.%s" % (label, item.lineno, node.name, item.name))
                targets = item.targets if isinstance(item, ast.Assign) else []
                if any(isinstance(t, ast.Name) and t.id == "__slots__" for t in targets):
                    found.append("%s:%d %s.__slots__" % (label, item.lineno, node.name))
        elif isinstance(node, ast.FunctionDef):
            for dec in node.decorator_list:
                name = dec.id if isinstance(dec, ast.Name) else dec.attr if isinstance(dec, ast.Attribute) else ""
                if name in ("property", "setter", "getter", "deleter", "cached_property"):
                    found.append("%s:%d @%s %s" % (label, dec.lineno, name, node.name))
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "property":
            found.append("%s:%d property()" % (label, node.lineno))
    return found


def test_no_portable_class_has_a_property_or_an_attribute_hook():
    offenders = []
    classes = 0
    for name in _portable_modules():
        found, n = class_offenders(importlib.import_module(name))
        offenders += found
        classes += n
    assert classes > 60, classes  # the scan found the portable classes
    assert not offenders, "%s: %s" % (WHY, offenders)


def test_no_property_or_attribute_hook_in_the_source_of_portable_or_board_code():
    offenders = []
    files = [ROOT / "compat.py"]
    for d in PORTABLE + BOARD:
        files += sorted((ROOT / d).rglob("*.py"))
    for path in files:
        offenders += source_offenders(path.read_text(), str(path.relative_to(ROOT)))
    assert len(files) > 50, len(files)
    assert not offenders, "%s: %s" % (WHY, offenders)


def test_the_checks_find_a_property_a_hook_and_an_inherited_one():
    # What the two checks above must catch, on made-up classes.
    import types

    src = """
class Base:
    @property
    def armed(self):
        return self._armed


class Stage(Base):
    pass


class Hooked:
    def __setattr__(self, name, value):
        object.__setattr__(self, name, value)


class Plain:
    x = property(lambda self: 1)

    def get_x(self):
        return 1
"""
    mod = types.ModuleType("made_up")
    exec(compile(src, "made_up", "exec"), mod.__dict__)
    offenders, classes = class_offenders(mod)
    assert classes == 4
    assert sorted(offenders) == ["made_up.Base.armed", "made_up.Hooked.__setattr__", "made_up.Plain.x",
                                 "made_up.Stage.armed"]
    found = source_offenders(src, "made_up")
    assert sorted(found) == ["made_up:13 Hooked.__setattr__", "made_up:18 property()", "made_up:3 @property armed"]
