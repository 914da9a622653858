"""Where the host loop of `sac_jax.run.run_training` is: the record a checkpoint keeps beside
the training state, so that a resumed run goes on counting chunks, clocks and evaluation times
where it stopped.

    position = Position()                       # a new run
    meta = {"position": position.to_json()}     # JSON in the checkpoint's metadata
    position = Position.from_json(meta["position"])
"""

from __future__ import annotations

import dataclasses
from typing import Dict


@dataclasses.dataclass
class Position:
    """env_steps: environment steps of one seed done (the checkpoint's step);
    chunks_done: compiled chunks run;
    startup_s: process start to the run's start; compile_s: building the program (and, on
        resume, reading the checkpoint), summed over resumes; run_s: training seconds,
        compile excluded; host_s: of those, the host's work between chunks;
    walls: {environment step of an evaluation point: run_s when the host reached it};
    non_finite: {run index: environment step at the end of the chunk in which its state first
        became non-finite} (a sweep trains on past a diverged setting);
    ends_run: whether the run ends at this position (its last point, or a stop): a checkpoint
        writer saves such a position whatever its interval."""

    env_steps: int = 0
    chunks_done: int = 0
    startup_s: float = 0.0
    compile_s: float = 0.0
    run_s: float = 0.0
    host_s: float = 0.0
    walls: Dict[int, float] = dataclasses.field(default_factory=dict)
    non_finite: Dict[int, int] = dataclasses.field(default_factory=dict)
    ends_run: bool = False

    def copy(self) -> Position:
        """A copy that later changes to this one do not reach."""
        return dataclasses.replace(self, walls=dict(self.walls), non_finite=dict(self.non_finite))

    def to_json(self) -> dict:
        """A JSON object (the dicts' keys as strings)."""
        record = dataclasses.asdict(self)
        record["walls"] = {str(k): v for k, v in self.walls.items()}
        record["non_finite"] = {str(k): v for k, v in self.non_finite.items()}
        return record

    @classmethod
    def from_json(cls, record: dict) -> Position:
        """The position `to_json` wrote; a field an earlier sac-jax did not store takes its
        default. A wrong type raises TypeError or ValueError."""
        if not isinstance(record, dict):
            raise TypeError(f"position {record!r} is not a JSON object")
        known = {f.name for f in dataclasses.fields(cls)} & record.keys()
        position = cls(**{name: record[name] for name in known})
        return dataclasses.replace(
            position, env_steps=int(position.env_steps), chunks_done=int(position.chunks_done),
            startup_s=float(position.startup_s), compile_s=float(position.compile_s),
            run_s=float(position.run_s), host_s=float(position.host_s),
            walls={int(k): float(v) for k, v in position.walls.items()},
            non_finite={int(k): int(v) for k, v in position.non_finite.items()},
            ends_run=bool(position.ends_run))
