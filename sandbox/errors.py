"""The project's named errors: each carries one line a person can act on."""


class SandboxError(Exception):
    """Base class: the CLI prints the message (one line) and exits non-zero, never a traceback."""


class SceneError(SandboxError):
    """A scene file (or an override) is invalid. The message names the file, the key and what was expected."""

    def __init__(self, file: str, key: str, expected: str):
        self.file, self.key, self.expected = file, key, expected
        where = f"key '{key}'" if key else "file"
        super().__init__(f"{file}: {where}: {expected}")


class SimulationError(SandboxError):
    """The simulation reached a state it cannot continue from (non-finite values, runaway energy)."""


class OutputError(SandboxError):
    """An output could not be written (a full disk, a quota, a failed encoder): `path` and the system's reason."""

    def __init__(self, path, reason: str, kept: list | None = None):
        self.path, self.reason, self.kept = path, reason, kept or []
        message = f"could not write {path}: {reason}"
        if self.kept:
            message += f"; the outputs so far are kept under partial names: {', '.join(str(p) for p in self.kept)}"
        super().__init__(message)
