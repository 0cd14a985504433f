"""The compiled JSON matcher (gridmap_cli/readers/ros/_cjson.c) takes exactly the messages the numpy
matcher of json_bulk.py takes, with the same values, on sound messages and on damaged or odd
ones; and its numbers are the floats ``json.loads`` gives, to the bit."""

from __future__ import annotations

import json
import math
import struct
from typing import Any

import numpy as np
import pytest

from gridmap_cli.readers.ros.mcap import json_bulk
from gridmap_cli.readers.ros.walk import compiled_walk
from tests.readers.test_json_bulk import compact_reading, raw_of

TYPES = sorted(json_bulk.JSON_TYPES)


@pytest.fixture
def walk(monkeypatch: pytest.MonkeyPatch) -> Any:
    monkeypatch.setenv("GRIDMAP_KERNELS", "compiled")  # built by the dev install: no skip
    return compiled_walk()


def c_match(walk: Any, type_name: str, texts: list[bytes]) -> tuple[list[bool], list[Any]]:
    """Each message's flag and the fields' values (one array, or (indexes, names), a field)."""
    raw = raw_of(texts)
    kinds = [p for p in json_bulk._COMPACT[type_name] if isinstance(p, str)]
    outs = tuple(np.zeros(len(texts), np.float64 if k == "num" else np.int64) for k in kinds)
    ok = np.zeros(len(texts), np.uint8)
    layout = json_bulk._C_LAYOUT[type_name]
    names = walk.json_compact(raw.buf, raw.offset, raw.length, layout, outs, ok)
    values = [o if n is None else (o, n) for o, n in zip(outs, names, strict=True)]
    return ok.astype(bool).tolist(), values


def row_values(cols: json_bulk.Columns) -> list[tuple[Any, ...]]:
    """The rows of columns as (stamp, name, numbers...), floats as their bits."""
    a = cols.arrays
    name = "child" if "child" in a else "sensor"
    numbers = [k for k in ("x", "y", "theta", "range") if k in a]
    bits = [a[k].view(np.int64) for k in numbers]
    return [
        (int(a["stamp_ns"][i]), cols.names[name][int(a[name][i])], *(b[i] for b in bits))
        for i in range(len(a["stamp_ns"]))
    ]


def sound(rng: np.random.Generator, type_name: str) -> bytes:
    """A message in gridmap's compact layout, with numbers of many spellings."""
    spellings = [repr(float(rng.normal() * 10.0 ** rng.integers(-8, 8))),
                 str(rng.integers(-99, 99)), "NaN", "Infinity", "-Infinity", "-0", "-0.0",
                 "1e5", "2.5E-3", "0.942", "4.335",
                 f"{rng.integers(1, 10**9)}e{rng.integers(-40, 40)}"]  # fmt: skip

    def num() -> str:
        return spellings[int(rng.integers(len(spellings)))]

    stamp = {"sec": int(rng.integers(0, 10**9)), "nsec": int(rng.integers(0, 10**9))}
    head = json.dumps({"timestamp": stamp}, separators=(",", ":"))[:-1]
    name = ("sonar0", "sonar15", "", "base_link", "a-b_c.d/e", "x" * 64)[int(rng.integers(6))]
    if type_name == "gridmap.Pose2D":
        numbers = f'"x":{num()},"y":{num()},"theta":{num()}}}'
        body = f',"frame_id":"odom","child_frame_id":"{name}",{numbers}'
    else:
        body = f',"sensor":"{name}","range":{num()}}}'
    return (head + body).encode()


ALPHABET = b'0123456789-+.eE",}{:\\\x00 \t\nNIaxn\x7f\x80\xff'


def damaged(rng: np.random.Generator, text: bytes) -> bytes:
    """``text`` with one to three bytes changed, inserted or deleted."""
    b = bytearray(text)
    for _ in range(int(rng.integers(1, 4))):
        at = int(rng.integers(0, len(b) + 1))
        byte = ALPHABET[int(rng.integers(len(ALPHABET)))]
        what = int(rng.integers(3))
        if what == 0 and at < len(b):
            b[at] = byte
        elif what == 1:
            b.insert(at, byte)
        elif at < len(b):
            del b[at]
    return bytes(b)


def c_row(values: list[Any], k: int) -> tuple[Any, ...]:
    """Message ``k``'s row as :func:`row_values` gives it, from the compiled matcher's values."""
    fields = [v[1][int(v[0][k])] if isinstance(v, tuple) else v[k : k + 1] for v in values]
    name = [f for f in fields if isinstance(f, str)][-1]  # the child frame or the sensor
    numbers = [f.view(np.int64)[0] for f in fields[2:] if not isinstance(f, str)]
    return (int(fields[0][0]) * 1_000_000_000 + int(fields[1][0]), name, *numbers)


@pytest.mark.parametrize("type_name", TYPES)
def test_compiled_matcher_agrees_with_numpy(walk: Any, type_name: str) -> None:
    rng = np.random.default_rng(17)
    texts = []
    for k in range(1500):
        text = sound(rng, type_name)
        texts.append(text if k % 3 == 0 else damaged(rng, text))
    flags, values = c_match(walk, type_name, texts)
    decode = json_bulk._pose2d if type_name == "gridmap.Pose2D" else json_bulk._reading
    taken = []
    for k, text in enumerate(texts):
        raw = raw_of([text])
        want = json_bulk._compact_numpy(type_name, raw)
        assert flags[k] == (want is not None), text
        if want is None:
            continue
        taken.append(text)
        assert c_row(values, k) == row_values(want)[0], text
        # and what the matchers take, json reads to the same values
        assert row_values(decode(raw, [json.loads(text)]))[0] == row_values(want)[0], text
    assert 100 < len(taken) < len(texts) - 100  # some edits keep the layout, most break it
    # one call over the taken messages: the same columns as the numpy matcher, names included
    raw = raw_of(taken)
    cols = json_bulk._compact_compiled(walk, type_name, raw)
    want = json_bulk._compact_numpy(type_name, raw)
    assert cols is not None and want is not None
    assert row_values(cols) == row_values(want)
    assert cols.names == want.names


def test_names_of_damaged_messages_are_not_kept(walk: Any) -> None:
    texts = [compact_reading("1", "5", "s0", "1"), compact_reading("1", "5", "s1", "1x"),
             compact_reading("1", "5", "s2", "2")]  # fmt: skip
    flags, values = c_match(walk, "gridmap.RangeReading", texts)
    assert flags == [True, False, True]
    index, names = values[2]
    assert names == ["s0", "s2"]
    assert index[[0, 2]].tolist() == [0, 1]


@pytest.mark.parametrize(
    "odd",
    [
        compact_reading("1", "5", "s0", "1.5\x00"),  # json stops at a NUL: so must the matchers
        compact_reading("1\x00", "5", "s0", "1.5"),
        compact_reading("1", "5", "s\x00", "1.5"),
        compact_reading("1", "5", "s0", "0x10"),
        compact_reading("1", "5", "s0", "inf"),
        compact_reading("1", "5", "s0", "1_0"),
        compact_reading("1", "5", "s0", " 1"),
        compact_reading("1", "5", "s0", "1" * 33),  # beyond 32 characters
        compact_reading("1", "5", "s" * 65, "1"),  # beyond 64
        compact_reading("-", "5", "s0", "1"),
        compact_reading("1", "5", "s0", "-"),
        compact_reading("1", "5", "s0", ".5"),
        compact_reading("1", "5", "s0", "1e+"),
        compact_reading("1", "5", "s0", "00.5"),
    ],
)
def test_what_json_refuses_neither_matcher_takes(walk: Any, odd: bytes) -> None:
    assert c_match(walk, "gridmap.RangeReading", [odd])[0] == [False]
    assert json_bulk._compact_numpy("gridmap.RangeReading", raw_of([odd])) is None


def number_texts(rng: np.random.Generator) -> list[str]:
    """Spellings of numbers: the shortest reprs of random doubles of every magnitude,
    subnormals and halfway cases included, random digit strings with exponents, integers."""
    bits = rng.integers(0, 2**63, size=3000, dtype=np.int64)
    doubles = [float(v) for v in bits.view(np.float64) if math.isfinite(float(v))]
    texts = [repr(v) for v in doubles] + [repr(-v) for v in doubles[:500]]
    texts += [repr(float(v)) for v in rng.uniform(-50, 50, 2000)]
    texts += [f"{float(v):.3f}" for v in rng.uniform(0, 5, 500)]
    for _ in range(3000):
        digits = "".join(str(d) for d in rng.integers(0, 10, int(rng.integers(1, 26))))
        digits = digits.lstrip("0") or "0"
        point = int(rng.integers(0, len(digits) + 1))
        text = digits if point == len(digits) else f"{digits[:point] or '0'}.{digits[point:]}"
        if rng.integers(2):
            text += f"e{int(rng.integers(-340, 330))}"
        texts.append(text if rng.integers(2) else "-" + text)
    halfway = [2**53 + 1, 2**54 + 2, 2**60 + 2**7, 10**22 + 1, 9007199254740993 * 10**5]
    texts += [str(v) for v in halfway] + [f"{v}e-10" for v in halfway]
    texts += ["0", "-0", "-0.0", "0e99", "-0e-99", "1e22", "1e23", "9007199254740992e22",
              "4.9e-324", "2.4703282292062327e-324", "2.4703282292062328e-324", "1e-400",
              "1.7976931348623157e308", "1.7976931348623159e308", "123456789012345678901234567890",
              "NaN", "Infinity", "-Infinity", "0.1", "0.3", "1E+2", "1e+0022"]  # fmt: skip
    return [t for t in texts if len(t) <= 32]


def test_numbers_are_the_floats_json_gives(walk: Any) -> None:
    rng = np.random.default_rng(3)
    spellings = number_texts(rng)
    texts = [compact_reading("1", "5", "s0", v) for v in spellings]
    flags, values = c_match(walk, "gridmap.RangeReading", texts)
    assert all(flags)
    want = np.array([float(json.loads(v)) for v in spellings], dtype=np.float64)
    got = values[3]
    for text, g, w in zip(spellings, got.view(np.int64), want.view(np.int64), strict=True):
        assert g == w, (text, struct.pack("<q", g).hex(), struct.pack("<q", w).hex())
