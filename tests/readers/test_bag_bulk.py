"""Bulk reading of ROS 1 bags (gridmap_cli/readers/ros/bag/bulk.py): the same canonical log as the
rosbags reader message by message, and the same survey from the index section alone."""

from __future__ import annotations

from pathlib import Path

import pytest

from gridmap_cli.readers.ros.bag import bulk as bag_bulk
from gridmap_cli.readers.ros.bag.log import BagSource, read_bag
from gridmap_cli.readers.ros.mcap import bulk as mcap_bulk
from tests.readers.bag_helpers import write_bag
from tests.readers.test_mcap_bulk import assert_same, busy_log


def test_bulk_equals_message_by_message(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    bag = write_bag(busy_log(tmp_path / "busy.mcap", 2), tmp_path / "busy.bag")
    topics = ["/odom", "/ground_truth", "/sonar", "/tf_static", "/tf"]
    batches, left = BagSource(bag).bulk(topics)
    assert left == []
    assert {b.topic for b in batches} == set(topics)
    in_bulk = read_bag(bag).log
    monkeypatch.setattr(mcap_bulk, "BULK_DECODE", False)
    assert_same(in_bulk, read_bag(bag).log)


def test_survey_from_the_index_is_rosbags_survey(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    bag = write_bag(busy_log(tmp_path / "busy.mcap", 2), tmp_path / "busy.bag")
    quick = BagSource(bag).survey()
    monkeypatch.setattr(bag_bulk, "survey_bag", lambda path: None)
    assert quick == BagSource(bag).survey()


def test_a_truncated_bag_falls_back(tmp_path: Path) -> None:
    bag = write_bag(busy_log(tmp_path / "busy.mcap", 2), tmp_path / "busy.bag")
    cut = tmp_path / "cut.bag"
    cut.write_bytes(bag.read_bytes()[:-100])
    assert bag_bulk.survey_bag(cut) is None
    assert bag_bulk.read_bulk(cut, ["/sonar"]) == ([], ["/sonar"])
