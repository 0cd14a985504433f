"""The typed decoder of json_bulk.py (msgspec) takes a message only where ``json.loads`` takes it,
and then gives the values the json way gives, to the bit: on sound messages of many spellings,
on damaged ones, and on numbers of every magnitude."""

from __future__ import annotations

import json
import math
import struct
from typing import Any

import numpy as np
import pytest

from gridmap_cli.readers.ros.bulk import Columns, Layout
from gridmap_cli.readers.ros.mcap import json_bulk
from tests.readers.test_json_bulk import compact_reading, raw_of

TYPES = sorted(json_bulk.JSON_TYPES)


def row_values(cols: Columns) -> list[tuple[Any, ...]]:
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
                 str(rng.integers(-99, 99)), "-0", "-0.0", "1e5", "2.5E-3", "0.942", "4.335",
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


ALPHABET = b'0123456789-+.eE",}{:[]\\\x00 \t\nNIaxntru\x7f\x80\xff'


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


def json_way(type_name: str, texts: list[bytes]) -> Columns:
    """What the json way builds from ``json.loads`` of each message."""
    build = json_bulk._pose2d if type_name == "gridmap.Pose2D" else json_bulk._reading
    return build(raw_of(texts), [json.loads(t) for t in texts])


@pytest.mark.parametrize("type_name", TYPES)
def test_typed_takes_what_json_takes_with_its_values(type_name: str) -> None:
    rng = np.random.default_rng(17)
    taken, refused = [], 0
    for k in range(1500):
        text = sound(rng, type_name)
        text = text if k % 3 == 0 else damaged(rng, text)
        cols = json_bulk._typed(type_name, raw_of([text]))
        if cols is None:
            refused += 1
            continue
        msg = json.loads(text)  # raises if msgspec took what json refuses
        assert type(msg) is dict, text
        assert row_values(cols) == row_values(json_way(type_name, [text])), text
        taken.append(text)
    assert len(taken) > 600 and refused > 300  # the sound ones and some edits; most edits break
    # one call over the taken messages: the same columns, names first seen first
    cols = json_bulk._typed(type_name, raw_of(taken))
    want = json_way(type_name, taken)
    assert cols is not None
    assert row_values(cols) == row_values(want)
    assert cols.names == want.names


@pytest.mark.parametrize(
    "odd",
    [
        compact_reading("1", "5", "s0", "1.5\x00"),  # json stops at a NUL: so must msgspec
        compact_reading("1\x00", "5", "s0", "1.5"),
        compact_reading("1", "5", "s\x00", "1.5"),
        compact_reading("1", "5", "s0", "0x10"),
        compact_reading("1", "5", "s0", "inf"),
        compact_reading("1", "5", "s0", "1_0"),
        compact_reading("-", "5", "s0", "1"),
        compact_reading("1", "5", "s0", "-"),
        compact_reading("1", "5", "s0", ".5"),
        compact_reading("1", "5", "s0", "1e+"),
        compact_reading("1", "5", "s0", "00.5"),
        compact_reading("1", "5", "s0", "1").replace(b"s0", b"s\xff"),  # not UTF-8
        b"\xef\xbb\xbf" + compact_reading("1", "5", "s0", "1"),
    ],
)
def test_what_json_refuses_or_bulk_does_not_take(odd: bytes) -> None:
    assert json_bulk._typed("gridmap.RangeReading", raw_of([odd])) is None
    with pytest.raises(Layout):
        json_bulk.decode("gridmap.RangeReading", raw_of([odd]))


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
    return [*texts, "1" * 400]


def test_numbers_are_the_floats_json_gives() -> None:
    """msgspec's number where it takes one, else the json way's (NaN, the infinities, numbers
    beyond a double): float of what ``json.loads`` gives, to the bit, or a Layout."""
    spellings = number_texts(np.random.default_rng(3))
    texts = [compact_reading("1", "5", "s0", v) for v in spellings]
    refused = []
    for text, spelling in zip(texts, spellings, strict=True):
        cols = json_bulk._typed("gridmap.RangeReading", raw_of([text]))
        if cols is None:
            refused.append(spelling)
            continue
        got = cols.arrays["range"].view(np.int64)[0]
        want = np.array([float(json.loads(spelling))]).view(np.int64)[0]
        assert got == want, (spelling, struct.pack("<q", got).hex(), struct.pack("<q", want).hex())
    assert len(refused) < len(spellings) // 20
    for spelling in refused:  # json reads them to a value a double cannot be finite at
        try:
            value = float(json.loads(spelling))
        except OverflowError:
            with pytest.raises(Layout, match="beyond a double"):
                json_bulk.decode("gridmap.RangeReading", raw_of([texts[spellings.index(spelling)]]))
            continue
        assert not math.isfinite(value), spelling
