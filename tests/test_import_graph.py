"""No import circles in src/hoverfly: the modules form a layered graph.

A circle means neither module can be read, tested or loaded without the other, and which half
of it runs first depends on who imported it first: on MicroPython a partly initialised module
raises AttributeError/ImportError at boot on one path and not on another. Deferring an import into
a function only hides a circle, so imports inside functions count too. The usual cure is the one
drivers/detect.py, protocols/rxfactory.py and sim/storagefile.py took: the part that needs both
sides goes into a module of its own.
"""

import ast
import pathlib

SRC = pathlib.Path(__file__).resolve().parent.parent / "src"


def _modules():
    """{dotted module name: path} for every module of the hoverfly package."""
    mods = {}
    for path in sorted((SRC / "hoverfly").rglob("*.py")):
        parts = list(path.relative_to(SRC).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        mods[".".join(parts)] = path
    return mods


def _resolve(name, mods):
    """The hoverfly module an imported name lives in (a name inside a module gives the module)."""
    while name and name not in mods:
        name = name.rpartition(".")[0]
    return name or None


def import_graph(mods=None):
    """{module: {hoverfly modules it imports anywhere in its source}}."""
    mods = _modules() if mods is None else mods
    graph = {}
    for name, path in mods.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        deps = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    up = package.split(".")[: len(package.split(".")) - node.level + 1]
                    base = ".".join(up + ([node.module] if node.module else []))
                # `from pkg import mod` imports the module pkg.mod; `from mod import name`, mod
                targets = [base + "." + a.name if base + "." + a.name in mods else base for a in node.names]
            else:
                continue
            for target in targets:
                found = _resolve(target, mods)
                if found and found != name:
                    deps.add(found)
        graph[name] = deps
    return graph


def find_cycles(graph):
    """Each group of modules that reach one another (strongly connected, more than one), as a
    sorted list, and for each one circle through it as a path that ends where it starts."""
    index, low, on_stack, stack, groups = {}, {}, set(), [], []
    counter = [0]

    def visit(v):  # Tarjan's algorithm, recursive: the package has a few hundred modules at most
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                group.append(w)
                if w == v:
                    break
            if len(group) > 1:
                groups.append(sorted(group))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return [(group, _circle(graph, group)) for group in groups]


def _circle(graph, group):
    """One path start -> ... -> start inside the group (breadth first from its first module)."""
    start = group[0]
    inside = set(group)
    came_from = {start: None}
    queue = [start]
    while queue:
        v = queue.pop(0)
        for w in sorted(graph[v]):
            if w == start:
                path = [v]
                while came_from[path[-1]] is not None:
                    path.append(came_from[path[-1]])
                return list(reversed(path)) + [start]
            if w in inside and w not in came_from:
                came_from[w] = v
                queue.append(w)
    return group


def test_src_hoverfly_has_no_import_circles():
    cycles = find_cycles(import_graph())
    assert not cycles, (
        "import circles in src/hoverfly (imports inside functions count: they only hide a circle, and on "
        "MicroPython a half-initialised module fails at boot on one import order and not another). Move what "
        "needs both sides into a module of its own (as drivers/detect.py, protocols/rxfactory.py):\n"
        + "\n".join("  " + " -> ".join(circle) for _, circle in cycles))


def test_the_circle_finder_finds_a_circle_deferred_into_a_function(tmp_path):
    # A base whose factory imports the implementations inside a function, each of them importing the
    # base: the shape drivers/imu.py and protocols/rxcodec.py had.
    pkg = tmp_path / "hoverfly"
    (pkg / "drivers").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "drivers" / "__init__.py").write_text("")
    (pkg / "drivers" / "base.py").write_text("def detect():\n    from hoverfly.drivers.chip import Chip\n")
    (pkg / "drivers" / "chip.py").write_text("from .base import detect\nclass Chip:\n    pass\n")
    (pkg / "drivers" / "other.py").write_text("from hoverfly.drivers import base\n")
    mods = {}
    for path in sorted(pkg.rglob("*.py")):
        parts = list(path.relative_to(tmp_path).with_suffix("").parts)
        mods[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    graph = import_graph(mods)
    assert graph["hoverfly.drivers.other"] == {"hoverfly.drivers.base"}
    cycles = find_cycles(graph)
    assert [group for group, _ in cycles] == [["hoverfly.drivers.base", "hoverfly.drivers.chip"]]
    assert cycles[0][1] == ["hoverfly.drivers.base", "hoverfly.drivers.chip", "hoverfly.drivers.base"]
