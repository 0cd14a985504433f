"""gzip-compressed text logs: the same records as the plain file, errors at the same lines."""

from __future__ import annotations

import gzip
from pathlib import Path

import numpy as np
import pytest

from gridmap_cli.errors import InputFileError
from gridmap_cli.readers import read_log, resolve_format

SAMPLES = Path(__file__).resolve().parents[2] / "samples"


def packed(tmp_path: Path, source: Path, name: str) -> Path:
    out = tmp_path / name
    out.write_bytes(gzip.compress(source.read_bytes()))
    return out


@pytest.mark.parametrize(
    ("sample", "fmt"), [("corridor_loop.csv", "csv"), ("corridor_loop.2d", "aria")]
)
def test_gzip_sample_reads_like_the_plain_one(tmp_path: Path, sample: str, fmt: str) -> None:
    plain = SAMPLES / sample
    for name in (f"{sample}.gz", "run.gz"):  # by the inner extension, then by sniffing
        gz = packed(tmp_path, plain, name)
        assert resolve_format(gz).name == fmt
        a, b = read_log(plain), read_log(gz)
        np.testing.assert_array_equal(a.poses.x_m, b.poses.x_m)
        np.testing.assert_array_equal(a.readings.stamp_ns, b.readings.stamp_ns)
        np.testing.assert_array_equal(a.readings.range_m, b.readings.range_m)
        assert a.sensor_names == b.sensor_names and b.source == str(gz)


def test_gzip_csv_error_keeps_path_and_line(tmp_path: Path) -> None:
    text = "time,x,y,theta,s0\n0.0,0,0,0,1.0\n0.1,0,0,oops,1.0\n"
    gz = tmp_path / "run.csv.gz"
    gz.write_bytes(gzip.compress(text.encode()))
    with pytest.raises(InputFileError) as err:
        read_log(gz)
    assert str(err.value) == f"{gz}:3: column 'theta': not a number: 'oops'"


def test_empty_gzip_member_is_an_empty_log(tmp_path: Path) -> None:
    gz = tmp_path / "run.csv.gz"
    gz.write_bytes(gzip.compress(b""))
    with pytest.raises(InputFileError, match="no header row"):
        read_log(gz)
