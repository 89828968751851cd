"""Project errors: every bad input becomes one line naming the file, the field and the expectation."""

from __future__ import annotations


class SwarmError(Exception):
    """Base class of the errors pybullet_swarm raises on purpose."""


class ConfigError(SwarmError, ValueError):
    """Bad configuration: a scenario, vehicle or override that cannot be used.

    The message is one line: ``file: field.path: what was expected, got what``.
    """

    def __init__(self, message: str, *, source: str | None = None, field: str | None = None) -> None:
        self.source = source
        self.field = field
        self.detail = " ".join(str(message).split())  # always one line
        parts = [p for p in (source, field) if p]
        super().__init__(": ".join([*parts, self.detail]))

    def with_source(self, source: str) -> ConfigError:
        """Return the same error attributed to ``source`` (a file name)."""
        return ConfigError(self.detail, source=source, field=self.field)


class SimulationError(SwarmError, RuntimeError):
    """The simulation cannot continue for a reason that is not bad input."""


class LayoutNeedError(ConfigError):
    """A layout check that a larger value of one field would pass.

    Raised by a plug-in's ``check_layout`` when the layout makes a field's value insufficient. When
    the scenario leaves that field unset, the scenario takes ``least`` for it (a derived value) and
    validates again; a value the user set is refused with this error, which says what would work.

    Attributes:
        least: the least value of ``field`` that passes this check.
    """

    def __init__(self, message: str, *, field: str, least: float, source: str | None = None) -> None:
        super().__init__(message, source=source, field=field)
        self.least = float(least)

    def with_source(self, source: str) -> LayoutNeedError:
        """Return the same error attributed to ``source`` (a file name)."""
        return LayoutNeedError(self.detail, source=source, field=self.field or "", least=self.least)
