"""open3d, imported without its browser viewer.

``import open3d`` runs ``open3d.visualization``, which imports ``draw_plotly``, which imports plotly and
dash (a web-app framework) at once: 0.3 s of the 0.6 s import, measured, in every camtool process that
queries a mesh (the free-form raster's chart mesh, the motion check's part). camtool never draws with
open3d. ``import_open3d`` puts a stand-in for ``open3d.visualization.draw_plotly`` in ``sys.modules``
before open3d's first import: the stand-in's functions import the real module when called (a user who
draws with open3d in the same process still can), and any other name asked of it does the same. open3d
itself offers no switch for this; hence by hand.
"""
from __future__ import annotations

import importlib
import sys
import types
from contextlib import contextmanager
from typing import Iterator

VIEWER = "open3d.visualization.draw_plotly"
VIEWER_NAMES = ("get_plotly_fig", "draw_plotly", "draw_plotly_server")   # what open3d.visualization imports


def import_open3d():
    """The open3d module (imported now if not yet, without plotly and dash)."""
    if "open3d" not in sys.modules and VIEWER not in sys.modules:
        sys.modules[VIEWER] = _ViewerStandIn(VIEWER)
    import open3d

    return open3d


def _real_viewer():
    """The real ``draw_plotly`` module, the stand-in dropped."""
    if isinstance(sys.modules.get(VIEWER), _ViewerStandIn):
        del sys.modules[VIEWER]
    return importlib.import_module(VIEWER)


class _ViewerStandIn(types.ModuleType):
    """``draw_plotly`` until something of it is used: its functions load the real module and call it."""

    def __init__(self, name: str):
        super().__init__(name)
        for fn in VIEWER_NAMES:
            setattr(self, fn, _loading(fn))

    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        return getattr(_real_viewer(), name)


def _loading(fn: str):
    def call(*args, **kwargs):
        return getattr(_real_viewer(), fn)(*args, **kwargs)

    call.__name__ = fn
    return call


@contextmanager
def open3d_quiet() -> Iterator[None]:
    """open3d prints its warnings on stdout; errors only while camtool calls it (our checks speak)."""
    o3d = import_open3d()

    with o3d.utility.VerbosityContextManager(o3d.utility.VerbosityLevel.Error):
        yield
