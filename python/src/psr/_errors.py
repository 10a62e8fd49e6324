"""psr's statuses as Python exceptions."""

from __future__ import annotations

from enum import IntEnum

from ._lib import LIB

__all__ = [
    "Status",
    "PsrError",
    "InvalidArgumentError",
    "EmptyInputError",
    "NonFiniteError",
    "ZeroNormalError",
    "InvalidParameterError",
    "CancelledError",
    "InvalidWeightError",
    "InvalidTransformError",
    "TooLargeError",
    "OutOfMemoryError",
    "ThreadsUnavailableError",
    "InternalError",
    "HandlePoisonedError",
    "FileError",
    "PlyError",
    "error_for",
]


class Status(IntEnum):
    """psr_status: what a psr function reports (0 is success; the numbers are stable)."""

    OK = 0
    NULL_ARGUMENT = 1
    INVALID_ARGUMENT = 2
    EMPTY_INPUT = 3
    NON_FINITE_POSITION = 4
    NON_FINITE_NORMAL = 5
    ZERO_NORMAL = 6
    INVALID_PARAMETER = 7
    CANCELLED = 8
    BUFFER_TOO_SMALL = 9
    HANDLE_POISONED = 10
    INTERNAL_ERROR = 11
    THREADS_UNAVAILABLE = 12
    NON_FINITE_ATTRIBUTE = 13
    INVALID_WEIGHT = 14
    INVALID_TRANSFORM = 15
    TOO_LARGE = 16
    OUT_OF_MEMORY = 17
    IO_ERROR = 18
    INVALID_FILE = 19


class PsrError(Exception):
    """An error reported by psr (or found by this package before calling it).

    ``status`` is psr's status (a :class:`Status`, or the raw int for a status this package does
    not know) and ``message`` the explanation psr gave (which argument, which point index, which
    parameter and its range). ``str(error)`` is ``"PSR_STATUS_NAME: message"``.
    """

    def __init__(self, status: int, message: str) -> None:
        try:
            self.status: Status | int = Status(status)
        except ValueError:
            self.status = status
        self.message = message
        name = LIB.psr_status_string(int(status)).decode()
        super().__init__(f"{name}: {message}" if message else name)


class InvalidArgumentError(PsrError, ValueError):
    """PSR_STATUS_INVALID_ARGUMENT (and NULL_ARGUMENT, BUFFER_TOO_SMALL): a malformed argument,
    such as an array of the wrong shape or arrays of different lengths."""


class EmptyInputError(PsrError, ValueError):
    """PSR_STATUS_EMPTY_INPUT: a solve without points."""


class NonFiniteError(PsrError, ValueError):
    """PSR_STATUS_NON_FINITE_POSITION, _NON_FINITE_NORMAL or _NON_FINITE_ATTRIBUTE: a NaN or
    infinite value (the message gives the index of the first one)."""


class ZeroNormalError(PsrError, ValueError):
    """PSR_STATUS_ZERO_NORMAL: a normal of zero length."""


class InvalidParameterError(PsrError, ValueError):
    """PSR_STATUS_INVALID_PARAMETER: a parameter out of its range, or two that disagree."""


class CancelledError(PsrError):
    """PSR_STATUS_CANCELLED: the progress callback asked to stop."""


class InvalidWeightError(PsrError, ValueError):
    """PSR_STATUS_INVALID_WEIGHT: a confidence weight negative, NaN or infinite, or all 0."""


class InvalidTransformError(PsrError, ValueError):
    """PSR_STATUS_INVALID_TRANSFORM: a transform with a non-finite entry, not affine or
    singular."""


class TooLargeError(PsrError, ValueError):
    """PSR_STATUS_TOO_LARGE: more vertices or points than 32-bit indices can name."""


class OutOfMemoryError(PsrError, MemoryError):
    """PSR_STATUS_OUT_OF_MEMORY: the solve needs more memory than ``max_memory`` allows
    (checked before allocating: from the point count, then the octree's node counts), or the
    system refused an allocation. The message names what needed how many bytes, the limit and,
    when known, the least limit that would do. The reconstructor stays usable."""


class ThreadsUnavailableError(PsrError, OSError):
    """PSR_STATUS_THREADS_UNAVAILABLE: the system refused to start worker threads."""


class FileError(PsrError, OSError):
    """PSR_STATUS_IO_ERROR: a file could not be opened, read, created or written (the message
    has the path and the system's reason)."""


class PlyError(PsrError, ValueError):
    """PSR_STATUS_INVALID_FILE: a file that is not PLY, or a PLY psr cannot read (malformed or
    truncated, no vertex x y z, a face index out of range); the message says where."""


class InternalError(PsrError, RuntimeError):
    """PSR_STATUS_INTERNAL_ERROR: a bug in psr (please report it)."""


class HandlePoisonedError(PsrError, RuntimeError):
    """PSR_STATUS_HANDLE_POISONED: an earlier internal error made the reconstructor unusable."""


_CLASSES: dict[int, type[PsrError]] = {
    Status.NULL_ARGUMENT: InvalidArgumentError,
    Status.INVALID_ARGUMENT: InvalidArgumentError,
    Status.EMPTY_INPUT: EmptyInputError,
    Status.NON_FINITE_POSITION: NonFiniteError,
    Status.NON_FINITE_NORMAL: NonFiniteError,
    Status.ZERO_NORMAL: ZeroNormalError,
    Status.INVALID_PARAMETER: InvalidParameterError,
    Status.CANCELLED: CancelledError,
    Status.BUFFER_TOO_SMALL: InvalidArgumentError,
    Status.HANDLE_POISONED: HandlePoisonedError,
    Status.INTERNAL_ERROR: InternalError,
    Status.THREADS_UNAVAILABLE: ThreadsUnavailableError,
    Status.NON_FINITE_ATTRIBUTE: NonFiniteError,
    Status.INVALID_WEIGHT: InvalidWeightError,
    Status.INVALID_TRANSFORM: InvalidTransformError,
    Status.TOO_LARGE: TooLargeError,
    Status.OUT_OF_MEMORY: OutOfMemoryError,
    Status.IO_ERROR: FileError,
    Status.INVALID_FILE: PlyError,
}


def error_for(status: int, message: str) -> PsrError:
    """The exception for a failed call's status (PsrError itself for an unknown one)."""
    return _CLASSES.get(status, PsrError)(status, message)
