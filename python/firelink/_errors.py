"""The exceptions of the ``firelink`` package.

Every error the native library reports arrives as one of these, with the
library's one-line message as ``str(exc)``.
"""

from __future__ import annotations

__all__ = [
    "FirelinkError",
    "ConfigError",
    "PortError",
    "BusError",
    "BusTimeout",
    "NoBoardsError",
    "InvalidRequest",
    "EmulatorClosed",
    "PacketError",
]


class FirelinkError(Exception):
    """Base class of every error raised by ``firelink``."""


class ConfigError(FirelinkError, ValueError):
    """A configuration is invalid.

    Attributes:
        file: the file as given to the loader (``"<string>"`` for text).
        path: the JSON path of the first problem, e.g.
            ``robots[0].actuators[2].drive.current_to_bits.scale``; empty for
            the whole document.
        problem: what is wrong there.
    """

    def __init__(self, message: str, file: str = "", path: str = "", problem: str = "") -> None:
        super().__init__(message)
        self.file = file
        self.path = path
        self.problem = problem


class PortError(FirelinkError, ValueError):
    """A port description is wrong, or the port is no longer usable."""


class BusError(FirelinkError):
    """A transaction failed (bad ack or rcode, bus reset, socket error...)."""


class BusTimeout(BusError, TimeoutError):
    """No answer in time."""


class NoBoardsError(BusError):
    """The scan found no board."""


class InvalidRequest(FirelinkError, ValueError):
    """An argument is of the wrong type or out of range (node, axis, board,
    length, duration, count, value...); the message names the argument,
    what was given and what is allowed."""


class EmulatorClosed(FirelinkError):
    """The emulator was stopped."""


class PacketError(FirelinkError, ValueError):
    """Bytes that are not a valid packet, or fields that make none."""
