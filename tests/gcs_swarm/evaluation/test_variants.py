"""Mission files derived for variants and randomised Monte Carlo worlds: they load, are reproducible per seed,
stay within their ranges and keep obstacles clear of the starts, goal and slots."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from gcs_swarm.evaluation import variants
from gcs_swarm.evaluation.variants import ObstacleRanges, Ranges, Variant, VariantError
from gcs_swarm.guidance.formation import rotate_to_world
from gcs_swarm.guidance.params import PAPER_PLAIN
from gcs_swarm.mission import load_mission
from gcs_swarm.mission.geometry import mission_offsets

ROOT = Path(__file__).resolve().parents[3]
QUICKSTART = ROOT / "missions" / "quickstart.yaml"
STATIC6 = ROOT / "missions" / "paper_static_6.yaml"


def test_variant_grid_combines_methods_controllers_and_winds() -> None:
    grid = variants.variant_grid(["apf", "iaapf"], ["smc", "pid"], [0.0, 5.0])
    assert len(grid) == 8
    assert grid[0].label == "apf-smc-wind0" and grid[-1].label == "iaapf-pid-wind5"
    assert variants.variant_grid(None, None, None) == [Variant()]
    assert Variant().label == "mission"


@pytest.mark.parametrize(
    ("methods", "controllers", "winds", "message"),
    [
        (["rrt"], None, None, "unknown variant 'rrt'"),
        (None, ["lqr"], None, "unknown controller 'lqr'"),
        (None, None, [-1.0], r"world.wind.speed: must be >= 0 m/s"),
        (["apf", "apf"], None, None, "listed twice"),
    ],
)
def test_variant_grid_refuses_bad_input(methods, controllers, winds, message) -> None:
    with pytest.raises(VariantError, match=message):
        variants.variant_grid(methods, controllers, winds)


def test_derived_variant_loads_with_its_settings(tmp_path: Path) -> None:
    variant = Variant(method="apf", controller="pid", wind_speed=7.5)
    mission = variants.derive_variant(QUICKSTART, variant, tmp_path / "v.yaml")
    assert mission.field.method == "apf"
    assert mission.controller == "pid"
    assert mission.wind.speed == 7.5
    assert mission.name == "quickstart-apf-pid-wind7.5"
    base = load_mission(QUICKSTART)
    assert mission.field.k_rep == base.field.k_rep == 1e5  # 1e5 survives the YAML round trip as a number
    assert mission.obstacles == base.obstacles


def _obstacles(mission) -> tuple[np.ndarray, np.ndarray]:
    return (
        np.array([o.center for o in mission.obstacles]).reshape(-1, 3),
        np.array([o.radius for o in mission.obstacles]),
    )


@pytest.mark.parametrize("source", [QUICKSTART, STATIC6])
def test_random_worlds_are_reproducible_within_ranges_and_clear_of_starts(
    source: Path, tmp_path: Path
) -> None:
    ranges = Ranges(obstacles=ObstacleRanges(count=(3, 5), radius=(2.0, 5.0), cross_track=(-8.0, 8.0)))
    base = load_mission(source)
    seen = set()
    for seed in range(6):
        a = variants.derive_monte_carlo_run(source, ranges, seed, Variant("apf"), tmp_path / f"a{seed}.yaml")
        b = variants.derive_monte_carlo_run(
            source, ranges, seed, Variant("iaapf"), tmp_path / f"b{seed}.yaml"
        )
        # The same seed gives the same world for every variant.
        assert a.obstacles == b.obstacles and a.wind == b.wind
        assert [v.start for v in a.vehicles] == [v.start for v in b.vehicles]
        assert a.field.method == "apf" and b.field.method == "iaapf"
        assert a.run.simulator.seed == seed
        centres, radii = _obstacles(a)
        seen.add(tuple(np.round(centres.ravel(), 3)))
        assert 3 <= len(radii) <= 5
        assert np.all((radii >= 2.0) & (radii <= 5.0))
        assert 0.0 <= a.wind.speed <= 5.0 and 0.0 <= a.wind.turbulence <= 0.5
        starts = np.array([v.start.position for v in a.vehicles])
        base_starts = np.array([v.start.position for v in base.vehicles])
        assert np.abs(starts - base_starts).max() <= ranges.starts.position_jitter + 1e-9
        if base.run.airborne_start:
            gaps = np.linalg.norm(starts[:, None] - centres[None], axis=-1) - radii
        else:  # ground start: the vehicle climbs a vertical column above its start
            gaps = np.linalg.norm(starts[:, None, :2] - centres[None, :, :2], axis=-1) - radii
        assert gaps.min() > ranges.obstacles.keep_out
        leg = np.asarray(a.goal) - np.asarray(a.vehicles[a.leader_index].start.position)
        slots = np.asarray(a.goal) + rotate_to_world(mission_offsets(a), np.arctan2(leg[1], leg[0]))
        slot_gaps = np.linalg.norm(slots[:, None] - centres[None], axis=-1) - radii
        assert slot_gaps.min() > ranges.obstacles.keep_out
        velocities = np.array([v.start.velocity for v in a.vehicles])
        base_velocities = np.array([v.start.velocity for v in base.vehicles])
        assert np.abs(velocities - base_velocities).max() <= ranges.starts.velocity + 1e-9
    assert len(seen) == 6  # different seeds, different worlds
    first = (tmp_path / "a0.yaml").read_text()
    variants.derive_monte_carlo_run(source, ranges, 0, Variant("apf"), tmp_path / "again.yaml")
    assert (tmp_path / "again.yaml").read_text() == first


def test_ground_starts_stay_at_rest(tmp_path: Path) -> None:
    mission = variants.derive_monte_carlo_run(QUICKSTART, Ranges(), 3, Variant(), tmp_path / "m.yaml")
    assert all(not v.start.velocity.any() for v in mission.vehicles)
    assert all(v.start.position[2] == 0.0 for v in mission.vehicles)


def test_ranges_file_sets_keys_and_refuses_mistakes(tmp_path: Path) -> None:
    good = tmp_path / "ranges.yaml"
    good.write_text("obstacles: {count: [1, 1], radius: [3, 3], replace: false}\nwind: {speed: [2, 2]}\n")
    ranges = variants.load_ranges(good)
    assert (
        ranges.obstacles.count == (1, 1)
        and ranges.obstacles.replace is False
        and ranges.wind.speed == (2.0, 2.0)
    )
    assert ranges.starts == Ranges().starts
    mission = variants.derive_monte_carlo_run(QUICKSTART, ranges, 0, Variant(), tmp_path / "m.yaml")
    assert len(mission.obstacles) == len(load_mission(QUICKSTART).obstacles) + 1
    assert mission.wind.speed == 2.0
    assert variants.load_ranges(None) == Ranges()
    for text, message in [
        ("obstacle: {count: [1, 2]}", "obstacle: unknown key; did you mean 'obstacles'"),
        ("obstacles: {cnt: [1, 2]}", r"obstacles.cnt: unknown key"),
        ("obstacles: {count: 3}", r"obstacles.count: expected two numbers"),
        ("obstacles: {radius: [5, 2]}", "low 5 is above high 2"),
        ("obstacles: {count: [1.5, 2]}", r"obstacles.count\[0\]: expected a whole number"),
        ("starts: {position_jitter: -1}", "starts.position_jitter: must be >= 0 m"),
        ("obstacles: {replace: 1}", "expected true or false"),
        ("obstacles: [", "not valid YAML"),
        ("- 1", "expected a mapping of keys to values"),
    ]:
        bad = tmp_path / "bad.yaml"
        bad.write_text(text)
        with pytest.raises(VariantError, match=message):
            variants.load_ranges(bad)
    with pytest.raises(VariantError, match="cannot read"):
        variants.load_ranges(tmp_path / "missing.yaml")


def test_link_loss_is_drawn_per_seed_within_its_range(tmp_path: Path) -> None:
    assert variants.link_loss(Ranges(), 4) == 0.0  # default: no link loss
    path = tmp_path / "ranges.yaml"
    path.write_text("link: {loss: [0.01, 0.05]}\n")
    ranges = variants.load_ranges(path)
    draws = [variants.link_loss(ranges, seed) for seed in range(20)]
    assert all(0.01 <= p <= 0.05 for p in draws) and len(set(draws)) > 10
    assert draws == [variants.link_loss(ranges, seed) for seed in range(20)]
    # Drawn from its own stream: the worlds are those of a campaign without link loss.
    with_loss = variants.derive_monte_carlo_run(QUICKSTART, ranges, 2, Variant(), tmp_path / "a.yaml")
    without = variants.derive_monte_carlo_run(QUICKSTART, Ranges(), 2, Variant(), tmp_path / "b.yaml")
    assert with_loss.obstacles == without.obstacles
    path.write_text("link: {loss: [0, 1]}\n")
    with pytest.raises(VariantError, match="link.loss"):
        variants.load_ranges(path)


def test_impossible_placement_is_a_clear_error(tmp_path: Path) -> None:
    ranges = Ranges(obstacles=ObstacleRanges(count=(1, 1), radius=(500.0, 500.0)))
    with pytest.raises(VariantError, match="cannot place obstacle 1"):
        variants.derive_monte_carlo_run(QUICKSTART, ranges, 0, Variant(), tmp_path / "m.yaml")


def test_written_variant_is_plain_yaml(tmp_path: Path) -> None:
    variants.derive_variant(STATIC6, Variant(method="apf"), tmp_path / "v.yaml")
    data = yaml.safe_load((tmp_path / "v.yaml").read_text())
    assert data["guidance"]["method"] == "apf"
    assert isinstance(data["guidance"]["k_rep"], float)


def test_the_paper_form_turns_every_addition_off(tmp_path):
    """`--variants paper,smooth`: the paper variant's mission carries PAPER_PLAIN's values (read back through
    the mission loader), the smooth one the mission's own; crossed with methods when both are given."""
    grid = variants.variant_grid(["paper", "smooth"], None, None)
    assert [v.label for v in grid] == ["paper", "smooth"]
    base = Path(__file__).resolve().parents[3] / "missions" / "quickstart.yaml"
    plain = variants.derive_variant(base, grid[0], tmp_path / "paper.yaml")
    smooth = variants.derive_variant(base, grid[1], tmp_path / "smooth.yaml")
    for key, value in PAPER_PLAIN["guidance.reference"].items():
        assert getattr(plain.reference, key) == value
    for key, value in PAPER_PLAIN["guidance"].items():
        assert getattr(plain.field, key) == value
    assert plain.limits.tilt_rate_max_deg == 0.0 and smooth.limits.tilt_rate_max_deg > 0.0
    assert plain.smc.drag_adaptation == 0.0 and smooth.smc.drag_adaptation > 0.0
    assert smooth.reference.jerk_max > 0.0 and smooth.field.circulation > 0.0
    crossed = variants.variant_grid(["apf", "iaapf", "paper"], None, None)
    assert [v.label for v in crossed] == ["apf-paper", "iaapf-paper"]
