"""Which exceptions are the user's (a bad option, key, value or file: one line of message)
and which are the program's (a traceback)."""

from __future__ import annotations

import argparse
import difflib
import sys

#: raised by validation before work starts: a setting's value, a missing or existing file, a key
#: (and any OmegaConf or Hydra error: :func:`_config_errors`)
USER_ERRORS = (ValueError, FileNotFoundError, FileExistsError, NotADirectoryError, KeyError,
               PermissionError)


class _Never(Exception):
    """Stands for an exception class of a library that was never imported: nothing is one."""


def _config_errors() -> tuple[type, type, type, type]:
    """OmegaConf's base error and Hydra's HydraException, InstantiationException and
    MissingConfigException; :class:`_Never` for those of a library this process never imported
    (no exception can then be one of them), so that a command without configs (``mocap export``,
    ``mocap --help``) does not import Hydra to report a bad argument."""
    omega = hydra_exc = instantiation = missing = _Never
    if "omegaconf" in sys.modules:
        from omegaconf.errors import OmegaConfBaseException as omega
    if "hydra" in sys.modules:
        from hydra.errors import HydraException as hydra_exc
        from hydra.errors import InstantiationException as instantiation
        from hydra.errors import MissingConfigException as missing
    return omega, hydra_exc, instantiation, missing


class UsageError(ValueError):
    """A bad argument of an argparse command (an unknown option, a missing or invalid value)."""


class ArgumentParser(argparse.ArgumentParser):
    """argparse for ``mocap`` commands: a bad argument raises :class:`UsageError` (one line,
    ``mocap <command>: error: ...``, through :func:`mocap_cli.main.main`) instead of printing the
    usage and exiting; ``--help`` still prints the help."""

    def error(self, message: str):
        hint = ""
        if message.startswith("unrecognized arguments:"):
            options = [o for o in self._option_string_actions if o.startswith("--")]
            close = {a: difflib.get_close_matches(a.split("=")[0], options, n=1, cutoff=0.6)
                     for a in message.split(":", 1)[1].split() if a.startswith("-")}
            hint = "".join(f"; did you mean {c[0]}?" for c in close.values() if c)
        raise UsageError(f"{message}{hint} ({self.prog} --help)")


def _one_line(text: str) -> str:
    lines = [line.strip() for line in str(text).splitlines() if line.strip()]
    return " ".join(lines)


def _binding_error(exc: BaseException) -> bool:
    """A TypeError from calling a config's _target_ with arguments it does not take (a
    missing or unknown key): raised before the target's body runs, in Hydra's frame."""
    if not isinstance(exc, TypeError) or not (
            "unexpected keyword argument" in str(exc) or "required keyword-only argument" in str(exc)
            or "required positional argument" in str(exc)):
        return False
    tb = exc.__traceback__
    while tb is not None and tb.tb_next is not None:
        tb = tb.tb_next
    return tb is not None and "hydra" in tb.tb_frame.f_code.co_filename


def _is_user_error(exc: BaseException) -> bool:
    attempt = sys.modules.get("mocap.run_folder.attempt")      # (never imported: no note to find)
    if attempt is not None and attempt.DURING_WORK_NOTE in getattr(exc, "__notes__", ()):
        return False            # raised after the checks, while tracking: a programming error
    OmegaConfBaseException, HydraException, InstantiationException, _ = _config_errors()
    if isinstance(exc, InstantiationException):
        cause = exc.__cause__
        return cause is not None and (_is_user_error(cause) or (
            isinstance(cause, TypeError) and "unexpected keyword argument" in str(cause)))
    return isinstance(exc, (HydraException, OmegaConfBaseException, *USER_ERRORS)) or _binding_error(exc)


def _missing_config(message: str) -> str:
    """Hydra's "Could not find" message without the search path, the options on one line."""
    head, _, options = message.split("Config search path:")[0].partition("Available options in")
    if not options:
        return head
    group, _, names = options.partition(":")
    return f"{head.strip()} (available in{group}: {', '.join(names.split())})"


def user_error_message(exc: BaseException) -> str | None:
    """One line for a user error (None: a programming error, show the traceback).

    Hydra wraps a factory's ValueError in an InstantiationException: the message is the
    original one. A composition error (unknown key, missing config) adds its cause's first
    line (e.g. "Key 'foo' is not in struct")."""
    if not _is_user_error(exc):
        return None
    OmegaConfBaseException, HydraException, InstantiationException, MissingConfigException = _config_errors()
    while isinstance(exc, InstantiationException) and exc.__cause__ is not None:
        exc = exc.__cause__
    cause = exc.__cause__
    if isinstance(exc, ValueError) and isinstance(cause, OSError) and "configure handler" in str(exc):
        # Hydra's log file in the run folder: name the file, not the logging handler
        return f"cannot write {cause.filename} ({cause.strerror}): the run folder is not writable"
    if isinstance(exc, KeyError) and len(exc.args) == 1 and isinstance(exc.args[0], str):
        message = exc.args[0]           # KeyError's str() quotes its message
    else:
        message = str(exc)
    if isinstance(exc, MissingConfigException):
        message = _missing_config(message)
    cause = exc.__cause__
    if isinstance(exc, HydraException) and isinstance(cause, OmegaConfBaseException) and str(cause).strip():
        reason = str(cause).strip().splitlines()[0].strip()
        first, *rest = message.strip().splitlines() or [""]
        if reason not in message:
            message = f"{first.rstrip('.')}: {reason}" + (f" ({' '.join(rest).strip()})" if rest else "")
    return _one_line(message) or type(exc).__name__
