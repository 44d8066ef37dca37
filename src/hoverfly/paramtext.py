"""Betaflight-style parameter text: the `set name = value` lines of a `diff` or `dump`, read the one way
that `hoverfly params restore` and the ground station's diff upload both use.

A file that starts with `# diff`, or holds `defaults nosave`, is a diff: every name it does not list
means its default. The CLI housekeeping lines (`batch start`, `save`, ...) carry nothing.
"""

from hoverfly.core.config.params import PARAMS, check
from hoverfly.core.links.cliserver import format_value

_HOUSEKEEPING = ("batch start", "batch end", "save", "exit")


def parse_set_text(text):
    """({name: checked value}, is_diff, skipped, errors) from a diff or dump's text.

    `skipped` lists (line number, text) of lines that are not `set` lines (a note for the user);
    `errors` lists (line number, why) of `set` lines that name no parameter, hold no `=`, or a value
    out of range. A later `set` of the same name wins, as on the controller."""
    values = {}
    skipped = []
    errors = []
    is_diff = False
    for n, raw in enumerate(text.splitlines(), 1):
        line = raw.strip()
        low = line.lower()
        if not line:
            continue
        if line.startswith("#"):
            if n == 1 and low.startswith("# diff"):
                is_diff = True
            continue
        if low in _HOUSEKEEPING:
            continue
        if low == "defaults nosave":  # what follows is a diff from the defaults
            is_diff = True
            values = {}
            continue
        if not low.startswith("set "):
            skipped.append((n, line))
            continue
        body = line[4:]
        if "=" not in body:
            errors.append((n, "use set name = value"))
            continue
        name_text, value_text = body.split("=", 1)
        name, v, err = check(name_text.strip().lower(), value_text.strip())
        if err is not None:
            errors.append((n, err))
            continue
        values[name] = v
    return values, is_diff, skipped, errors


def parse_dump(lines):
    """{name: value} from a controller's `dump` reply; lines that are not valid `set` lines are left out."""
    current = {}
    for line in lines:
        if line.startswith("set ") and "=" in line:
            name, text = line[4:].split("=", 1)
            name, v, err = check(name.strip(), text.strip())
            if err is None:
                current[name] = v
    return current


def changes_to(current, wanted, is_diff):
    """[(name, controller value, wanted value)] in table order, for the values that differ; with
    is_diff, a name `wanted` leaves out goes back to its default."""
    out = []
    for r in PARAMS:
        name = r[0]
        if name in wanted:
            target = wanted[name]
        elif is_diff:
            target = r[1]
        else:
            continue
        if name in current and format_value(current[name]) != format_value(target):
            out.append((name, current[name], target))
    return out
