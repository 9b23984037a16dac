"""Mission files: schema, loader and the validated `Mission` (docs/mission-schema.md).

mission = load_mission("missions/quickstart.yaml")   # MissionError: "file:line: field: what is wrong"
world = mission.world()                               # what the simulator needs
"""

from gcs_swarm.mission.loader import load_mission, load_world, parse_mission
from gcs_swarm.mission.model import LinkSpec, Mission, OutageSpec, World
from gcs_swarm.mission.yaml_tree import MissionError

__all__ = [
    "LinkSpec",
    "Mission",
    "MissionError",
    "OutageSpec",
    "World",
    "load_mission",
    "load_world",
    "parse_mission",
]
