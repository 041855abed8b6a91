"""Resolving a sequence specification into ordered frame files."""

from __future__ import annotations

import pytest

from dynmesh.io.sequence import SequenceError, natural_key, resolve_sequence


def touch(directory, *names):
    directory.mkdir(parents=True, exist_ok=True)
    for name in names:
        (directory / name).write_text("")
    return directory


def names(paths):
    return [p.name for p in paths]


def test_natural_key_orders_numbers_by_value():
    assert sorted(["f10.obj", "f2.obj", "F1.obj", "f2b.obj"], key=natural_key) == ["F1.obj", "f2.obj", "f2b.obj", "f10.obj"]


def test_directory_lists_mesh_files_in_natural_order(tmp_path):
    touch(tmp_path, "frame10.obj", "frame2.obj", "frame1.PLY", "notes.txt", "frame3.obj.bak")
    (tmp_path / "frame0.obj").mkdir()  # a directory is not a frame
    assert names(resolve_sequence(tmp_path)) == ["frame1.PLY", "frame2.obj", "frame10.obj"]
    assert names(resolve_sequence(str(tmp_path), start=1)) == ["frame2.obj", "frame10.obj"]
    assert names(resolve_sequence(tmp_path, start=0, count=2)) == ["frame1.PLY", "frame2.obj"]


def test_directory_slicing_past_the_end_is_an_error(tmp_path):
    touch(tmp_path, "a1.obj", "a2.obj")
    with pytest.raises(SequenceError, match="start index 2"):
        resolve_sequence(tmp_path, start=2)
    with pytest.raises(SequenceError, match="3 requested"):
        resolve_sequence(tmp_path, start=0, count=3)


def test_empty_directory_error_names_it(tmp_path):
    touch(tmp_path, "readme.txt")
    with pytest.raises(SequenceError, match="no .obj or .ply files") as e:
        resolve_sequence(tmp_path)
    assert str(tmp_path) in str(e.value)


def test_glob_sorts_naturally_and_slices(tmp_path):
    touch(tmp_path / "a", "x_9.obj", "x_10.obj", "x_100.obj", "y_1.obj")
    pattern = str(tmp_path / "a" / "x_*.obj")
    assert names(resolve_sequence(pattern)) == ["x_9.obj", "x_10.obj", "x_100.obj"]
    assert names(resolve_sequence(pattern, start=1, count=1)) == ["x_10.obj"]


def test_glob_without_match_names_the_pattern(tmp_path):
    pattern = str(tmp_path / "nothing_*.ply")
    with pytest.raises(SequenceError) as e:
        resolve_sequence(pattern)
    assert pattern in str(e.value)


def test_printf_pattern_from_the_smallest_frame_until_a_gap(tmp_path):
    touch(tmp_path, "frame_0003.obj", "frame_0004.obj", "frame_0005.obj", "frame_0007.obj", "frame_2.obj")
    pattern = tmp_path / "frame_%04d.obj"
    assert names(resolve_sequence(pattern)) == ["frame_0003.obj", "frame_0004.obj", "frame_0005.obj"]
    assert names(resolve_sequence(pattern, start=4)) == ["frame_0004.obj", "frame_0005.obj"]
    assert names(resolve_sequence(pattern, start=7)) == ["frame_0007.obj"]


def test_printf_pattern_with_count_takes_exactly_that_many(tmp_path):
    touch(tmp_path, *(f"m{i}.ply" for i in range(1, 12)))
    pattern = str(tmp_path / "m%d.ply")
    assert names(resolve_sequence(pattern, start=9, count=3)) == ["m9.ply", "m10.ply", "m11.ply"]
    assert names(resolve_sequence(pattern, count=2)) == ["m1.ply", "m2.ply"]


def test_printf_missing_frame_is_named(tmp_path):
    touch(tmp_path, "f_001.obj", "f_002.obj", "f_004.obj")
    with pytest.raises(SequenceError, match="f_003.obj"):
        resolve_sequence(tmp_path / "f_%03d.obj", start=1, count=4)
    with pytest.raises(SequenceError, match="f_010.obj"):
        resolve_sequence(tmp_path / "f_%03d.obj", start=10)
    with pytest.raises(SequenceError, match="g_%03d.obj"):
        resolve_sequence(tmp_path / "g_%03d.obj")


def test_printf_literal_percent_and_bad_patterns(tmp_path):
    touch(tmp_path, "50%_1.obj", "50%_2.obj")
    assert names(resolve_sequence(tmp_path / "50%%_%d.obj")) == ["50%_1.obj", "50%_2.obj"]
    with pytest.raises(SequenceError, match="exactly one"):
        resolve_sequence(tmp_path / "%d_%d.obj")


def test_single_file_and_nonexistent_spec(tmp_path):
    touch(tmp_path, "one.obj")
    assert resolve_sequence(tmp_path / "one.obj") == [tmp_path / "one.obj"]
    with pytest.raises(SequenceError, match="no such file"):
        resolve_sequence(tmp_path / "two.obj")
    with pytest.raises(SequenceError, match="count"):
        resolve_sequence(tmp_path, count=0)
