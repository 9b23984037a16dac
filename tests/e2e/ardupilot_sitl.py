"""Real ArduCopter SITL vehicles for end-to-end tests and rehearsals (docs/ardupilot-sitl.md): one
`arducopter` process per vehicle of a mission, each in its own working directory, at the home its mission
start gives, sending to the ground station's `udpin:` port. Needs a built binary; not part of swarm-gcs."""

from __future__ import annotations

import os
import signal
import subprocess
from dataclasses import dataclass
from pathlib import Path

import pymap3d

from gcs_swarm.link.connection import parse_connection
from gcs_swarm.mission import Mission


@dataclass(frozen=True)
class SitlBuild:
    """The ArduCopter SITL binary and its default parameters (ARDUPILOT_SITL, ARDUPILOT_DEFAULTS)."""

    binary: Path
    defaults: Path

    @classmethod
    def from_environment(cls) -> SitlBuild | None:
        """The build the environment names, or None. The defaults file defaults to the copter.parm of the
        source tree the binary was built in (build/sitl/bin/arducopter -> Tools/autotest/default_params)."""
        binary = os.environ.get("ARDUPILOT_SITL")
        if not binary:
            return None
        path = Path(binary)
        defaults = os.environ.get("ARDUPILOT_DEFAULTS")
        tree = path.resolve().parents[3] if len(path.resolve().parents) > 3 else path.parent
        return cls(path, Path(defaults) if defaults else tree / "Tools/autotest/default_params/copter.parm")


def home_of(mission: Mission, index: int) -> str:
    """`--home` of vehicle `index`: the mission origin moved by its start position; heading in compass degrees
    (0 north, clockwise) from the start's yaw_deg (ENU, counter-clockwise from east)."""
    v = mission.vehicles[index]
    east, north, _ = (float(x) for x in v.start.position)
    lat0, lon0, alt0 = mission.origin
    lat, lon, alt = pymap3d.enu2geodetic(east, north, 0.0, lat0, lon0, alt0)
    heading = (90.0 - v.start.yaw_deg) % 360.0
    return f"{float(lat):.7f},{float(lon):.7f},{float(alt):.2f},{heading:.1f}"


def start_vehicles(mission: Mission, build: SitlBuild, workdir: Path) -> list[subprocess.Popen[bytes]]:
    """One arducopter per vehicle (instance K = vehicle index, sysid from the mission or K+1), fresh
    parameters (-w), serial0 sending to the vehicle's `udpin:` port. Stop them with `stop_vehicles`."""
    procs = []
    for k, v in enumerate(mission.vehicles):
        spec = parse_connection(v.connection)
        if spec.kind != "udpin":
            raise ValueError(
                f"{v.name}: a SITL vehicle sends to the ground station: use udpin:, not {spec.text}"
            )
        cwd = workdir / f"sitl{k}"
        cwd.mkdir(parents=True, exist_ok=True)
        sysid = v.sysid if v.sysid is not None else k + 1
        cmd = [str(build.binary), "--model", "quad", "--defaults", str(build.defaults), "-I", str(k)]
        cmd += ["--sysid", str(sysid), f"--home={home_of(mission, k)}", "-w"]
        cmd += ["--serial0", f"udpclient:127.0.0.1:{spec.port}"]
        log = (cwd / "arducopter.log").open("wb")
        procs.append(
            subprocess.Popen(cmd, cwd=cwd, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
        )
    return procs


def stop_vehicles(procs: list[subprocess.Popen[bytes]]) -> None:
    """Terminate (then kill) every SITL process and its group."""
    for proc in procs:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGTERM)
    for proc in procs:
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(10)
