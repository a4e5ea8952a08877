"""What a law declares besides its kernels: its options (a validated dataclass) and its cost model.

A law's options are the settings a user may give a run of that law (for ``mdr``: the spring
count ``k`` and the spring storage ``spring_dtype``).  A law declares them as a frozen dataclass
derived from :class:`Options`, one :func:`option` per field; everything else takes them from
there: ``simulate(..., k=8)`` and scene files (``[run] k = 8``) check them with it, checkpoints
store them, sweeps may vary them and the documentation lists them.  :class:`Cost` is the law's
rough run-time model, which a sweep uses to choose between running serially and on a cluster.
"""

from __future__ import annotations

import dataclasses
import numbers
from dataclasses import dataclass

from ..checks import check_choice, check_int

__all__ = ["Options", "option", "Cost"]


def option(default, doc: str, *, valid=None, units: str = "1", attribute: str | None = None):
    """A field of a law's :class:`Options`.

    ``valid`` : ``(lo, hi)`` for an integer in [lo, hi], or a tuple of the allowed values (strings);
    ``units`` : CF units of the value; ``attribute`` : the output attribute it is written as
    (default: its name).
    """
    return dataclasses.field(default=default, metadata={"doc": doc, "valid": valid, "units": units,
                                                         "attribute": attribute})


@dataclass(frozen=True)
class Options:
    """Base of a law's options: each field an :func:`option`, checked when the object is made.

    A bad value raises ``ValueError`` naming the option, the value and the valid range.
    """

    def __post_init__(self):
        for f in dataclasses.fields(self):
            object.__setattr__(self, f.name, _checked(f, getattr(self, f.name)))

    @classmethod
    def names(cls) -> tuple:
        return tuple(f.name for f in dataclasses.fields(cls))

    @classmethod
    def describe(cls) -> dict:
        """name -> (default, doc, valid, units) of every option (listings, documentation)."""
        return {f.name: (f.default, f.metadata["doc"], f.metadata["valid"], f.metadata["units"])
                for f in dataclasses.fields(cls)}

    def as_dict(self) -> dict:
        """The options as JSON-able values (checkpoints, output attributes)."""
        return dataclasses.asdict(self)

    def attributes(self) -> dict:
        """Output attributes: each option under its ``attribute`` name."""
        return {f.metadata["attribute"] or f.name: getattr(self, f.name) for f in dataclasses.fields(self)}


def _checked(f, value):
    valid = f.metadata["valid"]
    if isinstance(valid, tuple) and len(valid) == 2 and all(isinstance(v, numbers.Integral) for v in valid):
        return check_int(f.name, value, *valid)
    if valid is not None:
        return check_choice(f.name, value, valid)
    return value


@dataclass(frozen=True)
class Cost:
    """A law's run-time model [s], for choosing how to run a sweep (rough; measured on 2 shared cores).

    per_increment : Python-side work of one increment (Newton loop, recording), on one core;
    per_asperity_increment : kernel time per asperity and increment on one thread;
    scale_by : the name of an integer option that multiplies the kernel time (``mdr``: ``k``), or None.
    """

    per_increment: float
    per_asperity_increment: float
    scale_by: str | None = None

    def seconds(self, increments: int, n: int, options: Options, threads: int = 1) -> float:
        """Estimated wall time of a run of ``increments`` increments on ``n`` asperities."""
        per = self.per_asperity_increment * (getattr(options, self.scale_by) if self.scale_by else 1)
        return increments * (self.per_increment + per * n / max(1, threads))
