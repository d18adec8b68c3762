"""The shared finished runs of `tests/conftest.py` are guarded: a test that changes one is found
at the end of the session, every changed, added and removed file named."""

from tests.helpers import changed_files, file_digests


def test_a_changed_an_added_and_a_removed_file_are_each_named_and_nothing_else(tmp_path):
    (tmp_path / "trials").mkdir()
    for name in ("kept.csv", "changed.csv", "removed.csv", "trials/tavc_000.npz"):
        (tmp_path / name).write_text(name)
    before = file_digests(tmp_path)
    assert changed_files(before, tmp_path) == []
    (tmp_path / "changed.csv").write_text("changed.csv, damaged")
    (tmp_path / "removed.csv").unlink()
    (tmp_path / "trials" / "added.tmp").write_text("")
    assert changed_files(before, tmp_path) == ["changed.csv", "removed.csv", "trials/added.tmp"]


def test_a_file_rewritten_with_its_own_bytes_is_no_change(tmp_path):
    (tmp_path / "config.yaml").write_text("seed: 0\n")
    before = file_digests(tmp_path)
    (tmp_path / "config.yaml").write_text("seed: 0\n")
    assert changed_files(before, tmp_path) == []
