"""ins_fusion/fleet/store.py: one batch at a time writes a folder, and none leaves its lock file
behind."""

from __future__ import annotations

import pytest

from ins_fusion.fleet.store import StoreError, open_store

LOCK = ".batch.lock"


def test_a_batch_leaves_no_lock_file_and_the_next_one_can_start(tmp_path):
    for _ in range(2):
        with open_store(tmp_path, {"rate": 1}, force=False) as store:
            assert (tmp_path / LOCK).exists()
            assert store.outcome("none") is None
        assert not (tmp_path / LOCK).exists()


def test_a_second_batch_on_the_folder_is_refused_while_the_first_runs(tmp_path):
    with open_store(tmp_path, {"rate": 1}, force=False):
        with (
            pytest.raises(StoreError, match="another batch is writing"),
            open_store(tmp_path, {"rate": 1}, force=False),
        ):
            pass
        assert (tmp_path / LOCK).exists()  # the refused one took nothing away
    assert not (tmp_path / LOCK).exists()


def test_a_refused_batch_for_other_options_leaves_no_lock_file(tmp_path):
    with open_store(tmp_path, {"rate": 1}, force=False):
        pass
    with (
        pytest.raises(StoreError, match="other options"),
        open_store(tmp_path, {"rate": 2}, force=False),
    ):
        pass
    assert not (tmp_path / LOCK).exists()
