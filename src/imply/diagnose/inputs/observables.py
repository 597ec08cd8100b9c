"""What a fit reads from a push log beyond its displacements: one object, from the options to the fit."""

from __future__ import annotations

from dataclasses import dataclass

from imply.diagnose.inputs.pushlog import TRACK_OBSERVABLES


@dataclass(frozen=True)
class Observables:
    """Which of a log's measurements every hypothesis's fit must explain (each used only where the log has it).

    The defaults are :class:`imply.diagnose.analysis.DiagnoseOptions`'s (a test holds them equal)."""

    measured: bool = True  # weighed masses and measured frictions, held fixed
    stop_time: bool = True
    pusher_speed: bool = False
    track: bool = False  # the times the box covers fractions of its travel
    probes: bool = True  # free strokes, friction measurements and added-mass pushes beside the log

    def wants(self, aux: str) -> bool:
        """Whether an observable beside the displacement (a name of the effect tables' aux) is asked for."""
        if aux in TRACK_OBSERVABLES:
            return self.track
        return {"stop_time": self.stop_time, "pusher_speed": self.pusher_speed}.get(aux, False)

    @property
    def any_aux(self) -> bool:
        """Whether any observable beside the displacement is asked for (the effect tables then carry them)."""
        return self.stop_time or self.pusher_speed or self.track
