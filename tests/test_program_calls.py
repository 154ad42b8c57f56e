"""camtool.program.calls: an entry program and the programs it calls, each once, depth bounded."""
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from camtool.errors import BadInput
from camtool.program.calls import called_programs


@dataclass
class _Parsed:
    calls: list
    problems: list = field(default_factory=list)


def _walk(tmp_path, graph):
    for name in graph:
        (tmp_path / f"{name}.p").write_text("")
    return called_programs(tmp_path / "MAIN.p", lambda p: _Parsed(list(graph[p.stem])),
                           lambda folder, name: folder / f"{name}.p" if (folder / f"{name}.p").is_file() else None,
                           lambda name: f"no {name}.p")


def test_each_called_program_once_in_run_order_with_findings(tmp_path):
    out = _walk(tmp_path, {"MAIN": [(3, "A"), (4, "B"), (5, "A"), (6, "GONE")], "A": [], "B": []})
    assert [p.stem for p, _ in out] == ["MAIN", "A", "B"]
    assert out[0][1].problems == [f"{tmp_path / 'MAIN.p'}:5: A is called twice (or calls itself)",
                                  f"{tmp_path / 'MAIN.p'}:6: no GONE.p"]


def test_nesting_deeper_than_camtool_writes_is_refused(tmp_path):
    with pytest.raises(BadInput, match="nested deeper"):
        _walk(tmp_path, {"MAIN": [(1, "A")], "A": [(1, "B")], "B": [(1, "C")], "C": []})
