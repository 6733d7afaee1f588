"""Exceptions raised by chekhov; each message says what was wrong and where."""


class ChekhovError(Exception):
    """Base class of every chekhov error."""


class RobotError(ChekhovError):
    """A robot description or configuration is invalid (wrong joint count, unknown frame …)."""


class SceneError(ChekhovError):
    """A scene file is malformed: the message names the file, object and field."""


class IKError(ChekhovError):
    """No joint configuration reaches the requested end-effector pose."""
