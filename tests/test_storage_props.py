"""Storage properties: a save cut at any byte, a file truncated or corrupted anywhere, still boots
with the newest intact set (or defaults with the fault flag) and never raises."""

import random

from hypothesis import given, settings
from hypothesis import strategies as st

from hoverfly.core.config.params import PARAMS, Params
from hoverfly.core.config.storage import LOST, SLOT_BYTES, MemoryStorageBoard, Storage, parse_record

# rc_map is a permutation of 12345678: most numbers in its range are refused (params.rc_map_error); a
# servo-mixer rule's input refuses 12..14 inside its range (params.smix_input_error)
_INT_ROWS = [r for r in PARAMS if isinstance(r[1], int) and not isinstance(r[1], bool) and r[3] > r[2]
             and r[0] != "rc_map" and not (r[0].startswith("smix") and r[0].endswith("_input"))]


def _random_params(rng):
    p = Params()
    for r in rng.sample(_INT_ROWS, 5):
        assert p.set(r[0], rng.randint(r[2], r[3])) is None
    return p


def _history(seed, saves):
    rng = random.Random(seed)
    board = MemoryStorageBoard()
    s = Storage(board)
    s.load(Params())
    sets = []
    images = [b""]
    for _ in range(saves):
        p = _random_params(rng)
        assert s.save(p) is None
        sets.append(dict(p.values))
        images.append(board.image)
    return sets, images


@settings(max_examples=300, derandomize=True, deadline=None)
@given(st.integers(0, 10_000), st.integers(1, 4), st.integers(0, 2 * SLOT_BYTES))
def test_save_cut_at_any_byte_boots_the_new_or_the_previous_set(seed, saves, cut):
    sets, images = _history(seed, saves + 1)
    old, new = images[-2], images[-1]
    # An in-place write interrupted after `cut` bytes: the new bytes up to it, the old after it.
    image = new[:cut] + old[cut:]
    p = Params()
    Storage(MemoryStorageBoard(image)).load(p)
    assert p.values in (sets[-1], sets[-2])


@settings(max_examples=300, derandomize=True, deadline=None)
@given(st.integers(0, 10_000), st.integers(1, 4), st.integers(0, 2 * SLOT_BYTES))
def test_truncated_file_boots_an_intact_set_or_defaults_flagged(seed, saves, cut):
    sets, images = _history(seed, saves)
    image = images[-1][:cut]
    p = Params()
    s = Storage(MemoryStorageBoard(image))
    status = s.load(p)
    intact = [parse_record(image, k * SLOT_BYTES) for k in (0, 1)]
    intact = [r for r in intact if r is not None]
    if intact:
        newest = max(r[1] for r in intact)
        assert p.values == sets[newest - 1]
    else:
        assert p.values == Params().values
        assert (status == LOST and s.failed) or not image


@settings(max_examples=300, derandomize=True, deadline=None)
@given(st.integers(0, 10_000), st.integers(2, 4), st.lists(st.tuples(st.integers(0, 2 * SLOT_BYTES),
                                                                         st.integers(1, 255)), max_size=4))
def test_corrupted_bytes_boot_an_intact_set_and_never_a_mixture(seed, saves, flips):
    sets, images = _history(seed, saves)
    image = bytearray(images[-1])
    for pos, x in flips:
        if pos < len(image):
            image[pos] ^= x
    p = Params()
    Storage(MemoryStorageBoard(bytes(image))).load(p)
    assert p.values in sets or p.values == Params().values


@settings(max_examples=300, derandomize=True, deadline=None)
@given(st.binary(max_size=3 * SLOT_BYTES))
def test_any_bytes_load_without_raising(data):
    p = Params()
    s = Storage(MemoryStorageBoard(data))
    s.load(p)
    assert s.save(p) is None  # and the next save works
