"""Exceptions of pneumasim: each names the file, field or column at fault."""


class PneumasimError(Exception):
    """Base class: a user-facing error with a one-line message."""


class ConfigError(PneumasimError):
    """A model file (MJCF or TOML) is missing, malformed or inconsistent."""


class RecordingError(PneumasimError):
    """A recording (CSV) cannot be read or does not fit the model."""


class UnknownNameError(PneumasimError, KeyError):
    """A name (model, scenario, joint, actuator) that does not exist; lists the valid ones."""

    def __init__(self, kind: str, name: str, valid):
        self.kind, self.name, self.valid = kind, name, sorted(valid)
        super().__init__(f"unknown {kind} {name!r}; valid: {', '.join(self.valid)}")

    def __str__(self) -> str:  # KeyError would add quotes around the message
        return self.args[0]


class ArgumentError(PneumasimError, ValueError):
    """A Python API argument outside its valid range or of the wrong type; names the argument
    and what is valid.  A ValueError too, so ``except ValueError`` callers keep working."""
