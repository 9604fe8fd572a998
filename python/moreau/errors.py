"""The errors of Moreau in Python, local and remote alike.

The command line's exit codes have one exception type each:
  2  SceneError          an invalid scene (or study, campaign) naming its field by JSON pointer
  1  RunFailed           the run did not complete (the step failed, max_steps, a non-finite state)
  3  HypothesisFailed    with strict=True: a hypothesis the run relies on fails (the report says which)
and, talking to a server,
  ServerError            an error answer of the server (its HTTP status, error, reason and pointer);
                         about the scene, a ServerSceneError: a SceneError too
  ServerUnreachable      no answer at all (also a ConnectionError)
A run stopped by Ctrl-C raises KeyboardInterrupt, as any Python code does.
"""

from __future__ import annotations

from typing import Optional

__all__ = ["MoreauError", "SceneError", "RunFailed", "HypothesisFailed", "ServerError", "ServerSceneError",
           "ServerUnreachable"]


class MoreauError(Exception):
    """Every error of Moreau's: catch this to catch them all."""

    exit_code = 1


class SceneError(MoreauError, ValueError):
    """An invalid scene: `pointer` is the JSON pointer of the field ("/integrator/h"), `reason` what is
    wrong with it. The message is "<pointer>: <reason>", as the command line prints it."""

    exit_code = 2

    def __init__(self, message: str, pointer: str = "/", reason: str = "") -> None:
        super().__init__(message)
        self.pointer = pointer
        self.reason = reason or message


class RunFailed(MoreauError):
    """The run ended before t_end (status "failed" or "cancelled"); `result` holds what was computed,
    its report saying why."""

    exit_code = 1

    def __init__(self, message: str, result: object = None) -> None:
        super().__init__(message)
        self.result = result


class HypothesisFailed(MoreauError):
    """strict=True and a hypothesis the run relies on fails; `result` is the completed run."""

    exit_code = 3

    def __init__(self, message: str, result: object = None) -> None:
        super().__init__(message)
        self.result = result


class ServerError(MoreauError):
    """An error answer of the server: `status` (HTTP), `error` (short, stable), `reason` (what to change),
    `pointer` (a JSON pointer into the scene or the request, or None), `where` ("scene", "request" or None)."""

    def __init__(self, status: int, error: str, reason: str = "", pointer: Optional[str] = None, where: Optional[str] = None) -> None:
        text = "%d %s" % (status, error)
        if pointer is not None:
            text += " at %s%s" % (where + " " if where else "", pointer)
        if reason:
            text += ": " + reason
        super().__init__(text)
        # Set after the bases' __init__ (SceneError's sets pointer and reason too, for ServerSceneError).
        self.status = status
        self.error = error
        self.reason = reason
        self.pointer = pointer
        self.where = where


class ServerSceneError(ServerError, SceneError):
    """An error answer about the scene (`where` "scene", with its `pointer`): a ServerError and a
    SceneError both, so that `except SceneError` catches an invalid scene whether it ran here or there."""


class ServerUnreachable(MoreauError, ConnectionError):
    """No answer from the server: refused, reset, unknown host or timed out. `url` is the server's."""

    def __init__(self, url: str, reason: str) -> None:
        super().__init__("cannot reach the server %s: %s" % (url, reason))
        self.url = url
        self.reason = reason
