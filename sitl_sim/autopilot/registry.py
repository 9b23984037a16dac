"""The registry of the simulated autopilots' personas: every persona by its `--autopilot` name, the personas
of a fleet, and the fleet's one parameter table (each vehicle lists only its own persona's names).

The persona base class is sitl_sim.autopilot.persona; the personas are sitl_sim.autopilot.arducopter and
sitl_sim.autopilot.px4. An unknown name is refused, never mapped to a default.
"""

from __future__ import annotations

import numpy as np

from sitl_sim.autopilot.arducopter import ArduCopter
from sitl_sim.autopilot.params import ParamSpec, ParamTable
from sitl_sim.autopilot.persona import Persona
from sitl_sim.autopilot.px4 import Px4

# every persona by its `--autopilot` name
PERSONAS: dict[str, type[Persona]] = {persona.name: persona for persona in (ArduCopter, Px4)}


def persona_named(name: str) -> type[Persona]:
    """The persona called `name`; ValueError (a one-line reason) for a name no persona has."""
    if name not in PERSONAS:
        raise ValueError(f"--autopilot {name!r} is not one of {', '.join(PERSONAS)}")
    return PERSONAS[name]


def parse_autopilots(text: str, vehicles: int) -> tuple[str, ...]:
    """`--autopilot` text -> one persona name per vehicle: a single name applies to all, a comma list gives
    one per vehicle. Raises ValueError (a one-line reason) for an unknown name or a wrong count."""
    names = tuple(part.strip().lower() for part in text.split(","))
    for name in names:
        persona_named(name)
    if len(names) == 1:
        return names * vehicles
    if len(names) != vehicles:
        raise ValueError(f"--autopilot lists {len(names)} autopilots for {vehicles} vehicles")
    return names


def fleet_personas(names: tuple[str, ...], vehicles: int) -> tuple[type[Persona], ...]:
    """The persona of each of `vehicles` vehicles from their names (() : ArduCopter for all)."""
    return tuple(persona_named(name) for name in names) if names else (persona_named("ardupilot"),) * vehicles


def fleet_params(
    shared: tuple[ParamSpec, ...], hover_fraction: float, personas: tuple[type[Persona], ...]
) -> ParamTable:
    """One parameter table for a fleet whose vehicle i is personas[i]: the `shared` specs (the shared loop's
    columns, in ArduCopter's names and units) plus every persona's own (whether or not the fleet has one);
    each vehicle lists what its persona shows, and its hidden shared columns follow its persona's values
    (Persona.configure)."""
    kinds = tuple(PERSONAS.values())
    own = {kind: kind.param_specs(hover_fraction) for kind in kinds}
    specs = tuple(sorted(shared + tuple(s for kind in kinds for s in own[kind]), key=lambda spec: spec.name))
    is_shared = [spec in shared for spec in specs]
    shown = {
        kind: [kind.shows(spec, own[kind], flag) for spec, flag in zip(specs, is_shared, strict=True)]
        for kind in kinds
    }
    visible = np.array([shown[kind] for kind in personas])
    table = ParamTable(len(personas), specs, visible)
    for kind in kinds:
        kind.configure(table, np.flatnonzero([persona is kind for persona in personas]))
    return table
