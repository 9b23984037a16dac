"""The first formation tick costs what the later ones do (issue 35): PX4's OFFBOARD needs a setpoint stream
before it is accepted (`setpoint_proof_s` of vehicle time), and that stream is streamed before the first
formation tick, while the vehicles still hold in their launch mode, not inside that tick, where the guidance
would stand still while the vehicles fly on their last setpoint.

Read from the runner's own tick timing over a scripted fleet of PX4 vehicles whose "wall clock" is their
vehicle time, so that a tick that waits out the proof stream shows as the stream's length of work.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from gcs_swarm.flight.phase import Phase
from gcs_swarm.flight.runner import MissionRunner
from gcs_swarm.link.autopilots import AutopilotDialect, ModeChoice, mode_name_in
from gcs_swarm.link.autopilots.px4 import PX4
from gcs_swarm.mission import load_mission
from tests.gcs_swarm.flight.scripted_fleet import TICK_MS, ScriptedFleet, Sent

MISSIONS = Path(__file__).resolve().parents[3] / "missions"
START = np.array([[0.0, 0.0, 10.0], [-7.0, -7.0, 10.0], [-7.0, 7.0, 10.0]])  # at formation altitude, m ENU


class ScriptedPX4Fleet(ScriptedFleet):
    """ScriptedFleet whose vehicles speak PX4: OFFBOARD is accepted only after PX4.setpoint_proof_s of
    vehicle time of streamed position holds (Fleet.take_control_all streams them tick by tick)."""

    @property
    def dialects(self) -> list[AutopilotDialect]:
        return [PX4] * len(self.names)

    def mode_number(self, i: int, mode: ModeChoice) -> int:
        return PX4.mode_number(mode_name_in(PX4, mode))

    def set_mode_all(self, mode: ModeChoice, vehicles: Iterable[int] | None = None) -> None:
        name = mode_name_in(PX4, mode)
        for i in self._rows(vehicles):
            self.sent.append(Sent(self.now_ms, i, "mode", name))
            self.state.mode[i] = PX4.mode_number(name)

    def take_control_all(self, vehicles: Iterable[int] | None = None) -> None:
        rows = self._rows(vehicles)
        for _ in range(math.ceil(PX4.setpoint_proof_s * 1000 / TICK_MS)):
            for i in rows:
                self.sent.append(Sent(self.now_ms, i, "position"))
            self.wait_tick(0.0)
        self.set_mode_all(PX4.formation_mode, rows)


def test_offboard_proof_stream_runs_before_the_first_formation_tick() -> None:
    fleet = ScriptedPX4Fleet(["lead", "right", "left"], START)
    fleet.state.mode[:] = PX4.mode_number(PX4.launch_mode)  # holding after the takeoff
    fleet.state.armed[:] = True
    runner = MissionRunner(
        load_mission(MISSIONS / "quickstart.yaml"), fleet, None, progress=lambda line: None
    )  # type: ignore[arg-type]
    runner.tick_timing.clock = lambda: fleet.now_ms / 1000.0  # vehicle time stands in for the wall clock
    runner.command_launch = lambda: None  # type: ignore[method-assign]  # launched already (state above)
    runner._set_phase(Phase.LAUNCH)

    proof_ms = math.ceil(PX4.setpoint_proof_s * 1000 / TICK_MS) * TICK_MS
    runner.start_formation()
    for _ in range(5):
        runner.step()

    assert runner.phase is Phase.FORMATION
    offboard = [s for s in fleet.sent if s.kind == "mode" and s.value == "OFFBOARD"]
    assert len(offboard) == 3 and offboard[0].t_ms >= 100_000 + proof_ms  # after the whole proof stream
    first_attitude_ms = min(s.t_ms for s in fleet.sent if s.kind == "attitude")
    assert first_attitude_ms > offboard[0].t_ms  # formation commands only once OFFBOARD is set
    rows = np.array(runner.tick_timing.rows)  # (t_s, wait_s, work_s, ...) per formation tick
    assert len(rows) == 6  # start_formation's tick and five steps
    per_tick = rows[:, 1] + rows[:, 2]  # vehicle s each tick took, waiting included
    # each tick, the first included, spans one control period: the proof stream is not inside any of them
    np.testing.assert_allclose(per_tick, TICK_MS / 1000.0, atol=1e-9)
