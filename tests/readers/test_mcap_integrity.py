"""MCAP integrity: every CRC the file carries is checked, length fields are not trusted, and
the error names the byte offset of the damage (issue 11)."""

from __future__ import annotations

import struct
import zlib
from collections.abc import Iterator
from pathlib import Path

import pytest
from mcap.writer import CompressionType

from gridmap_cli.readers.ros.mcap.integrity import MAX_CHUNK_BYTES, McapDamage, verify_mcap
from tests.corpus.mcap_edit import edit_mcap
from tests.helpers import names, run

SAMPLE = Path(__file__).resolve().parents[2] / "samples" / "corridor_loop.mcap"
CHUNK, DATA_END, FOOTER, MESSAGE_INDEX, CHUNK_INDEX = 0x06, 0x0F, 0x02, 0x07, 0x08


def rewrite(target: Path, compression: CompressionType, **kwargs: bool) -> Path:
    """The corridor sample rewritten with other compression and CRC settings; small chunks, so
    there are several."""
    options = {"enable_data_crcs": False, **kwargs}  # the mcap writer's defaults otherwise
    return edit_mcap(SAMPLE, target, compression=compression, chunk_size=64 * 1024, **options)


def records(data: bytes) -> Iterator[tuple[int, int, int]]:
    """(offset, opcode, length) of the file's top-level records."""
    pos = 8
    while pos < len(data) - 8:
        opcode, length = data[pos], struct.unpack_from("<Q", data, pos + 1)[0]
        yield pos, opcode, length
        pos += 9 + length


def first(data: bytes, opcode: int, nth: int = 0) -> tuple[int, int]:
    found = [(pos, length) for pos, op, length in records(data) if op == opcode]
    return found[nth]


@pytest.fixture(scope="module")
def plain(tmp_path_factory: pytest.TempPathFactory) -> bytes:
    """Uncompressed chunks, every CRC written (chunks, data section, summary)."""
    folder = tmp_path_factory.mktemp("plain")
    return rewrite(folder / "p.mcap", CompressionType.NONE, enable_data_crcs=True).read_bytes()


@pytest.fixture(scope="module")
def zstd(tmp_path_factory: pytest.TempPathFactory) -> bytes:
    folder = tmp_path_factory.mktemp("zstd")
    return rewrite(folder / "z.mcap", CompressionType.ZSTD, enable_data_crcs=True).read_bytes()


@pytest.fixture(scope="module")
def no_crcs(tmp_path_factory: pytest.TempPathFactory) -> bytes:
    """No CRC at all: only the length checks can catch lies."""
    folder = tmp_path_factory.mktemp("nocrc")
    return rewrite(folder / "n.mcap", CompressionType.NONE, enable_crcs=False).read_bytes()


def build_fails(tmp_path: Path, data: bytes | bytearray) -> str:
    """Build the damaged file: exit 1, one Error line naming the file; nothing written."""
    log = tmp_path / "bad.mcap"
    log.write_bytes(bytes(data))
    before = names(tmp_path)
    code, _, err = run("build", str(log), "-o", str(tmp_path / "m.png"))
    assert code == 1, err
    assert err.count("\n") == 1 and err.startswith(f"Error: {log}: byte "), err
    assert names(tmp_path) == before
    return err


def test_the_undamaged_files_pass(
    plain: bytes, zstd: bytes, no_crcs: bytes, tmp_path: Path
) -> None:
    for name, data in (("p", plain), ("z", zstd), ("n", no_crcs)):
        (tmp_path / f"{name}.mcap").write_bytes(data)
        verify_mcap(tmp_path / f"{name}.mcap")
    verify_mcap(SAMPLE)


def test_a_changed_digit_in_an_uncompressed_chunk_is_refused(plain: bytes, tmp_path: Path) -> None:
    pos, length = first(plain, CHUNK, 1)
    data = bytearray(plain)
    at = pos + length // 2
    data[at] = ord("7") if data[at] != ord("7") else ord("3")
    err = build_fails(tmp_path, data)
    assert f"byte {pos}: chunk CRC mismatch" in err


def test_a_wrong_chunk_crc_field_is_refused(zstd: bytes, tmp_path: Path) -> None:
    pos, _ = first(zstd, CHUNK)
    data = bytearray(zstd)
    crc_at = pos + 9 + 24  # after the two times and uncompressed_size
    data[crc_at] ^= 0x01
    assert f"byte {pos}: chunk CRC mismatch" in build_fails(tmp_path, data)


def test_a_flipped_byte_in_a_zstd_chunk_is_one_line_not_a_traceback(
    zstd: bytes, tmp_path: Path
) -> None:
    pos, length = first(zstd, CHUNK)
    for delta in (60, length // 3, length - 5):
        data = bytearray(zstd)
        data[pos + delta] ^= 0xFF
        err = build_fails(tmp_path, data)
        assert f"byte {pos}: " in err
        assert "ZstdError" in err or "CRC mismatch" in err or "decompresses to" in err


def test_damage_between_chunks_fails_the_data_section_crc(plain: bytes, tmp_path: Path) -> None:
    pos, _ = first(plain, MESSAGE_INDEX)
    data = bytearray(plain)
    data[pos + 9 + 4] ^= 0x10  # inside the record's body, its length unchanged
    end, _ = first(plain, DATA_END)
    assert f"byte {end}: data section CRC mismatch" in build_fails(tmp_path, data)


def test_damage_in_the_summary_fails_the_summary_crc(plain: bytes, tmp_path: Path) -> None:
    data = bytearray(plain)
    data[len(data) - 8 - 29 - 40] ^= 0x01
    assert "summary CRC mismatch" in build_fails(tmp_path, data)


def test_a_record_length_claiming_more_than_the_file_is_caught(
    no_crcs: bytes, tmp_path: Path
) -> None:
    pos, _ = first(no_crcs, MESSAGE_INDEX)
    data = bytearray(no_crcs)
    struct.pack_into("<Q", data, pos + 1, 1 << 40)
    err = build_fails(tmp_path, data)
    assert f"byte {pos}: record (opcode 0x07) claims {1 << 40} bytes" in err


def test_a_chunk_records_length_that_lies_is_caught(no_crcs: bytes, tmp_path: Path) -> None:
    pos, _ = first(no_crcs, CHUNK)
    data = bytearray(no_crcs)
    records_length_at = pos + 9 + 8 + 8 + 8 + 4 + 4  # compression "" (length 0) follows
    struct.pack_into("<Q", data, records_length_at, 12)
    assert f"byte {pos}: chunk claims 12 bytes of records" in build_fails(tmp_path, data)


def test_a_record_inside_a_chunk_that_lies_about_its_length_is_caught(
    no_crcs: bytes, tmp_path: Path
) -> None:
    pos, _ = first(no_crcs, CHUNK)
    data = bytearray(no_crcs)
    inner = pos + 9 + 40  # the chunk's first record (compression "")
    struct.pack_into("<Q", data, inner + 1, 1 << 32)
    err = build_fails(tmp_path, data)
    assert f"byte {pos}: record at byte 0 of the chunk's data claims {1 << 32} bytes" in err


def test_an_uncompressed_size_beyond_the_limit_is_refused_naming_it(
    no_crcs: bytes, tmp_path: Path
) -> None:
    pos, _ = first(no_crcs, CHUNK)
    data = bytearray(no_crcs)
    struct.pack_into("<Q", data, pos + 9 + 16, 1 << 50)
    err = build_fails(tmp_path, data)
    assert f"above gridmap's limit of {MAX_CHUNK_BYTES} bytes per chunk" in err


def test_a_chunk_index_pointing_elsewhere_is_caught(no_crcs: bytes, tmp_path: Path) -> None:
    pos, _ = first(no_crcs, CHUNK_INDEX)
    data = bytearray(no_crcs)
    chunk_start_at = pos + 9 + 16
    (offset,) = struct.unpack_from("<Q", data, chunk_start_at)
    struct.pack_into("<Q", data, chunk_start_at, offset + 9)
    assert f"byte {pos}: chunk index points at" in build_fails(tmp_path, data)


def test_verify_reports_the_offset_as_a_field(plain: bytes, tmp_path: Path) -> None:
    path = tmp_path / "t.mcap"
    path.write_bytes(plain[:-1])
    with pytest.raises(McapDamage) as info:
        verify_mcap(path)
    assert info.value.offset == len(plain) - 1


def test_the_first_damaged_chunk_is_named_when_the_data_crc_covers_them(
    plain: bytes, tmp_path: Path
) -> None:
    """With a data section CRC the chunks' own CRCs are checked only once damage is found:
    a changed digit in one chunk is still named before a lying length in a later one."""
    damaged, _ = first(plain, CHUNK, 1)
    later, _ = first(plain, CHUNK, 3)
    data = bytearray(plain)
    digits = [i for i in range(damaged + 9 + 60, later) if chr(data[i]).isdigit()]
    data[digits[0]] = ord("7") if data[digits[0]] != ord("7") else ord("3")
    struct.pack_into("<Q", data, later + 9 + 40 + 1, 1 << 32)  # its first record's length
    err = build_fails(tmp_path, data)
    assert f"byte {damaged}: chunk CRC mismatch" in err
    data[digits[0]] = plain[digits[0]]  # the later damage alone: its chunk's CRC, as before
    assert f"byte {later}: chunk CRC mismatch" in build_fails(tmp_path, data)


def test_a_chunk_crc_left_to_the_data_crc_passes_when_that_matches(
    plain: bytes, tmp_path: Path
) -> None:
    """The data section CRC covers every stored byte of the chunks: a chunk CRC field that
    disagrees with its intact records (written so, not damaged since) is not checked."""
    pos, _ = first(plain, CHUNK)
    data = bytearray(plain)
    data[pos + 9 + 24] ^= 0x01  # the chunk's uncompressed_crc field
    end, _ = first(plain, DATA_END)
    struct.pack_into("<I", data, end + 9, zlib.crc32(bytes(data[:end])))
    path = tmp_path / "rewritten.mcap"
    path.write_bytes(bytes(data))
    verify_mcap(path)
