"""Mission files: schema, loader and the validated `Mission` (docs/mission-schema.md).

mission = load_mission("missions/quickstart.yaml")   # MissionError: "file:line: field: what is wrong"
world = mission.world()                               # what the simulator needs
"""

from gcs_swarm.mission.loader import load_mission, load_world, parse_mission
from gcs_swarm.mission.model import (
    FormationSpec,
    LinkSpec,
    Mission,
    Obstacle,
    OutageSpec,
    PlannerSpec,
    RunSpec,
    SafetySpec,
    SimulatorSpec,
    StartState,
    VehicleSpec,
    WindSpec,
    World,
)
from gcs_swarm.mission.yaml_tree import MissionError

__all__ = [
    "FormationSpec",
    "LinkSpec",
    "Mission",
    "MissionError",
    "Obstacle",
    "OutageSpec",
    "PlannerSpec",
    "RunSpec",
    "SafetySpec",
    "SimulatorSpec",
    "StartState",
    "VehicleSpec",
    "WindSpec",
    "World",
    "load_mission",
    "load_world",
    "parse_mission",
]
