"""The CamtoolError hierarchy; the CLI maps each class to an exit code.

| class            | exit | meaning                                     |
|------------------|------|---------------------------------------------|
| BadInput         | 2    | bad input or usage (file, key, value)       |
| PlanInfeasible   | 3    | the plan cannot be done (unreachable, ...)  |
| StageUnavailable | 4    | a pipeline stage is not available yet       |
| CamtoolError     | 1    | internal error (any other failure)          |

Messages are one line a process engineer can act on.
"""

import difflib


def closest(word: str, known) -> str:
    """ "; did you mean X?" for the closest known name, or "" (for unknown-key messages)."""
    match = difflib.get_close_matches(word, list(known), n=1, cutoff=0.6)
    return f"; did you mean {match[0]!r}?" if match else ""


class CamtoolError(Exception):
    """Base class of every error camtool raises on purpose."""

    exit_code = 1


class BadInput(CamtoolError):
    """Bad input: a file, a key, a value or a usage the user can fix."""

    exit_code = 2


class PlanInfeasible(CamtoolError):
    """The plan cannot be done, e.g. unreachable points or broken limits."""

    exit_code = 3

    def __init__(self, message: str, report: dict | None = None):
        super().__init__(message)
        self.report = report or {}


class StageUnavailable(CamtoolError):
    """A pipeline stage that camtool does not have yet."""

    exit_code = 4
