"""CSV writer and reader: header with units, exact round trips, determinism."""
import numpy as np
import pytest

from camtool.errors import BadInput
from camtool.program.profiles import Profile
from camtool.program.profiles import default_options
from camtool.robots import BUILTIN_ROBOTS, get_robot
from post_fixtures import smooth_trajectory
from postprocessors.csv_joint import CsvPost, read_table

POST = CsvPost()


def _profile(unit):
    return Profile("<test>", "csv", options={**default_options("csv"), "angle_unit": unit})


@pytest.mark.parametrize("robot_name", BUILTIN_ROBOTS)
def test_round_trip_in_radians_is_exact(robot_name, tmp_path):
    r = get_robot(robot_name)
    tr = smooth_trajectory(r, 97)
    f = POST.write(tr, r, _profile("rad"), tmp_path)[0]
    t_s, q = POST.read_trajectory(f, r)
    assert np.array_equal(t_s, tr.t_s) and np.array_equal(q, tr.q)
    dur, q2 = POST.read(f, r, None)
    assert np.isnan(dur[0]) and np.array_equal(dur[1:], np.diff(tr.t_s)) and np.array_equal(q2, tr.q)


def test_degrees_file_values_are_exact(tmp_path):
    r = get_robot("seed8")
    tr = smooth_trajectory(r, 50)
    f = POST.write(tr, r, _profile("deg"), tmp_path)[0]
    header, data = read_table(f)
    assert header == ["t_s", "track_mm", "j2_deg", "j3_deg", "j4_deg", "j5_deg", "j6_deg", "j7_deg", "j8_deg"]
    assert np.array_equal(data[:, 0], tr.t_s)
    assert np.array_equal(data[:, 1], tr.q[:, 0])  # the track stays in mm
    assert np.array_equal(data[:, 2:], np.degrees(tr.q[:, 1:]))
    _t, q = POST.read_trajectory(f, r)
    assert np.abs(q - tr.q).max() < 1e-12


def test_radians_header(tmp_path):
    r = get_robot("irb2400")
    f = POST.write(smooth_trajectory(r, 3), r, _profile("rad"), tmp_path)[0]
    assert f.read_text().splitlines()[0] == "t_s,j1_rad,j2_rad,j3_rad,j4_rad,j5_rad,j6_rad"


def test_reader_refuses_columns_of_another_robot(tmp_path):
    r = get_robot("irb2400")
    f = POST.write(smooth_trajectory(r, 3), r, _profile("deg"), tmp_path)[0]
    with pytest.raises(BadInput, match="7 joints|robot sia20 has 7"):
        POST.read(f, get_robot("sia20"), None)
    f.write_text(f.read_text().replace("j3_deg", "j3_mm"))
    with pytest.raises(BadInput, match="joint j3 is revolute"):
        POST.read(f, r, None)


def test_bad_angle_unit_is_refused(tmp_path):
    r = get_robot("irb2400")
    with pytest.raises(BadInput, match="angle_unit"):
        POST.write(smooth_trajectory(r, 3), r, _profile("grad"), tmp_path)


def test_same_trajectory_gives_identical_bytes(tmp_path):
    r = get_robot("sia20")
    tr = smooth_trajectory(r, 40)
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    a = POST.write(tr, r, _profile("deg"), tmp_path / "a")[0].read_bytes()
    b = POST.write(tr, r, _profile("deg"), tmp_path / "b")[0].read_bytes()
    assert a == b


def test_the_last_line_is_the_row_count_trailer(tmp_path):
    r = get_robot("irb2400")
    f = POST.write(smooth_trajectory(r, 7), r, _profile("deg"), tmp_path)[0]
    lines = f.read_bytes().decode("ascii").split("\n")
    assert lines[-1] == "" and lines[-2] == "# END 7 rows" and len(lines) == 1 + 7 + 2
    assert np.loadtxt(f, delimiter=",", skiprows=1).shape == (7, 7)  # '#' is a comment for numpy
    header, data = read_table(f)  # the reader does not take the trailer for data
    assert header[0] == "t_s" and data.shape == (7, 7)


def test_reader_takes_a_file_without_trailer(tmp_path):
    """Older camtool CSVs had no trailer: they still read (the check flags them)."""
    r = get_robot("irb2400")
    tr = smooth_trajectory(r, 5)
    f = POST.write(tr, r, _profile("rad"), tmp_path)[0]
    f.write_text("\n".join(f.read_text().splitlines()[:-1]) + "\n")
    t_s, q = POST.read_trajectory(f, r)
    assert np.array_equal(t_s, tr.t_s) and np.array_equal(q, tr.q)
    assert any("no trailer" in x for x in POST.check(f, r, None))


def test_blocks_of_rows_give_the_same_file_and_table(tmp_path, monkeypatch):
    """The writer turns 20k rows to text at a time and the reader parses 20k at a time (a dense job's table
    at once is ~0.4 GB of text): in blocks of 7 rows the file and the table read back are the same."""
    from postprocessors.csv import parser, writer

    r = get_robot("seed8")
    tr = smooth_trajectory(r, 97)
    (tmp_path / "whole").mkdir()
    (tmp_path / "blocks").mkdir()
    whole = POST.write(tr, r, _profile("deg"), tmp_path / "whole")[0]
    monkeypatch.setattr(writer, "BLOCK_ROWS", 7)
    monkeypatch.setattr(parser, "BLOCK_ROWS", 7)
    blocks = POST.write(tr, r, _profile("deg"), tmp_path / "blocks")[0]
    assert blocks.read_bytes() == whole.read_bytes()
    t_s, q = POST.read_trajectory(blocks, r)
    assert np.array_equal(t_s, tr.t_s) and np.allclose(q, tr.q, rtol=0, atol=1e-12)
