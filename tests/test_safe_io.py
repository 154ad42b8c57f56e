"""camtool.safe_io: what the checks hand to libraries that open files by name."""
import os
from pathlib import Path


def test_a_private_copy_is_the_checked_bytes_and_no_file_on_disk(tmp_path):
    """A library that opens by name gets a memory file with the checked bytes: swapping the input for a
    FIFO afterwards changes nothing, and no file appears in the temporary folder."""
    import tempfile

    from camtool.safe_io import private_copy

    src = tmp_path / "part.step"
    src.write_bytes(b"ISO-10303-21;" + b"x" * 5000)
    before = set(Path(tempfile.gettempdir()).iterdir())
    with private_copy(src, "workpiece", ".step") as name:
        src.unlink()
        os.mkfifo(src)
        assert Path(name).read_bytes() == b"ISO-10303-21;" + b"x" * 5000
        assert set(Path(tempfile.gettempdir()).iterdir()) == before
