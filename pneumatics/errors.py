"""Exceptions of pneumasim: each names the file, field or column at fault."""
import difflib


class PneumasimError(Exception):
    """Base class: a user-facing error with a one-line message."""


class ConfigError(PneumasimError):
    """A model file (MJCF or TOML) is missing, malformed or inconsistent."""


class RecordingError(PneumasimError):
    """A recording (CSV) cannot be read or does not fit the model."""


class OutputError(PneumasimError):
    """An output path that cannot or must not be written (checked before any work starts)."""


def close_matches(name: str, valid, n: int = 3, cutoff: float = 0.7) -> list[str]:
    """The valid names nearest ``name`` (difflib's ratio >= ``cutoff``, case ignored), best first.
    0.7 keeps one-letter slips in short names ('arm3' -> 'arm2': 0.75) and drops look-alikes
    ('arm3_nothing' -> 'arm2_tracking': 0.64)."""
    lowered = {str(v).lower(): str(v) for v in valid}
    return [lowered[m] for m in difflib.get_close_matches(str(name).lower(), list(lowered), n=n, cutoff=cutoff)]


class UnknownNameError(PneumasimError, KeyError):
    """A name (model, scenario, joint, actuator, map, effect) that does not exist; suggests the
    nearest valid ones ("did you mean") and lists them all."""

    def __init__(self, kind: str, name: str, valid):
        self.kind, self.name, self.valid = kind, name, sorted(str(v) for v in valid)
        self.suggestions = close_matches(name, self.valid)
        hint = f" did you mean {' or '.join(repr(s) for s in self.suggestions)}?" if self.suggestions else ""
        super().__init__(f"unknown {kind} {name!r};{hint} valid: {', '.join(self.valid)}")

    def __str__(self) -> str:  # KeyError would add quotes around the message
        return self.args[0]


class ArgumentError(PneumasimError, ValueError):
    """A Python API argument outside its valid range or of the wrong type; names the argument
    and what is valid.  A ValueError too, so ``except ValueError`` callers keep working."""
