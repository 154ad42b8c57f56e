"""Output files: folders are made; impossible places are one clear BadInput."""
import pytest

from camtool.errors import BadInput
from camtool.files import output_file

from conftest import SAMPLES, run_camtool


def test_output_file_makes_the_folder(tmp_path):
    p = output_file(tmp_path / "a" / "b" / "c.json")
    assert p.parent.is_dir() and not p.exists()


def test_output_file_errors(tmp_path):
    with pytest.raises(BadInput, match="cannot create the folder"):
        output_file("/proc/camtool-nope/x.json")
    with pytest.raises(BadInput, match="is a folder"):
        output_file(tmp_path)


def test_cli_saves_into_new_folders(tmp_path):
    r = run_camtool("fit", SAMPLES / "plate_hole.stl", "--save", tmp_path / "new" / "surface.json")
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "new" / "surface.json").is_file()
