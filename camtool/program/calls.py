"""The programs of a run: an entry program, then every program it calls, for parsers whose controller
splits a long program into files one main program calls in turn (KRL modules, FANUC LS programs)."""
from __future__ import annotations

from pathlib import Path
from typing import Callable

from camtool.errors import BadInput

MAX_CALL_DEPTH = 2  # camtool writes a main program calling parts, and nothing deeper


def called_programs(entry: Path, parse: Callable, find: Callable[[Path, str], Path | None],
                    missing: Callable[[str], str]) -> list[tuple[Path, object]]:
    """``(file, parsed)`` of ``entry`` and, depth first, each program it calls, each once.

    ``parse(file)`` gives an object with ``calls`` (line, name) and a ``problems`` list; ``find(folder,
    name)`` the called program's file or None; ``missing(name)`` the finding for a call with no file. A
    program called twice (or calling itself) is a finding on the caller, a nesting deeper than camtool writes
    is BadInput."""
    out: list[tuple[Path, object]] = []
    seen: set[str] = set()

    def visit(p: Path, depth: int) -> None:
        if depth > MAX_CALL_DEPTH:
            raise BadInput(f"{p}: calls nested deeper than camtool writes them")
        parsed = parse(p)
        out.append((p, parsed))
        seen.add(p.stem.upper())
        for n, name in parsed.calls:
            if name.upper() in seen:
                parsed.problems.append(f"{p}:{n}: {name} is called twice (or calls itself)")
                continue
            q = find(p.parent, name)
            if q is None:
                parsed.problems.append(f"{p}:{n}: {missing(name)}")
                continue
            visit(q, depth + 1)

    visit(Path(entry), 0)
    return out
