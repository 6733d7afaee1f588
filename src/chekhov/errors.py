"""Exceptions raised by chekhov; each message says what was wrong and where."""


class ChekhovError(Exception):
    """Base class of every chekhov error."""


class RobotError(ChekhovError):
    """A robot description or configuration is invalid (wrong joint count, unknown frame …)."""


class SceneError(ChekhovError):
    """A scene file is malformed: the message names the file, object and field."""


class IKError(ChekhovError):
    """No joint configuration reaches the requested end-effector pose."""


class CaseFileError(ChekhovError):
    """A benchmark case file is missing, truncated, corrupt or of another scene (names the file)."""


class PlanningInputError(ChekhovError):
    """A planning query is malformed: wrong joint count, outside the joint limits, non-finite
    values, a bad tolerance or time limit (the message names the argument and what was given)."""


class BenchError(ChekhovError):
    """The benchmark runner cannot go on (database locked too long, unwritable output …)."""


class DeadlineError(ChekhovError):
    """A stage ran out of its query's time limit (planners answer "timeout")."""


class TrajectoryError(ChekhovError):
    """A malformed timed trajectory or trajectory file (names the field), or a time
    parameterisation that cannot be done."""
