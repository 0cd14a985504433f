"""gridmap's errors cross process boundaries (Dask workers, multiprocessing) unchanged."""

from __future__ import annotations

import pickle

import pytest

from gridmap_cli import errors as e


@pytest.mark.parametrize(
    "err",
    [
        e.GridmapError("plain"),
        e.UsageError("bad flag"),
        e.InputFileError("run.csv", "not a number", line=3, column="x"),
        e.DamagedAtError("run.bag", 120, "chunk cut short"),
        e.NotRecordingFolderError("logs/", "no metadata.yaml"),
        e.UnknownFormatError("run.xyz", "csv, bag", "text"),
        e.RobotDescriptionError("robot.yaml", "no sensors"),
        e.UnknownRobotError("p9", ["p3dx", "p3at"]),
        e.OutputExistsError("map.png"),
        e.NoDataError("nothing to map"),
    ],
)
def test_an_error_pickles_to_the_same_error(err: e.GridmapError) -> None:
    again = pickle.loads(pickle.dumps(err))
    assert type(again) is type(err)
    assert str(again) == str(err) and again.args == err.args
    assert vars(again) == vars(err)
