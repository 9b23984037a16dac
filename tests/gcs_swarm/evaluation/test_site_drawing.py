"""The site on the top views (evaluation.site_drawing): every fence, zone, building and tree of a mission is
drawn, once, where the mission puts it; a mission without a site gets no site figure."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from gcs_swarm.evaluation.site_drawing import draw_site, has_site  # noqa: E402
from gcs_swarm.mission import load_mission  # noqa: E402
from tests.e2e.flights import MISSIONS  # noqa: E402


def test_every_part_of_the_site_is_one_patch_where_the_mission_puts_it() -> None:
    mission = load_mission(MISSIONS / "cmac_site.yaml")
    fig, ax = plt.subplots()
    draw_site(ax, mission)
    patches = ax.patches
    # cmac/fence.plan: the inclusion pentagon, a clubhouse polygon and a pond circle excluded;
    # cmac/field.geojson: three buildings, three poplars and an oak
    assert len(patches) == 1 + 2 + 3 + 4
    fence, clubhouse, pond = patches[:3]
    np.testing.assert_allclose(fence.get_xy()[:-1], mission.fence.polygon)
    assert not fence.get_fill() and clubhouse.get_fill()
    np.testing.assert_allclose(pond.center, mission.fence.exclusions[1].center)
    assert pond.radius == mission.fence.exclusions[1].radius == 22.0
    oak = patches[-1]
    np.testing.assert_allclose(oak.center, mission.cylinders[-1].center)
    plt.close(fig)


def test_only_a_mission_with_a_site_or_legs_has_a_site_figure() -> None:
    assert has_site(load_mission(MISSIONS / "cmac_site.yaml"))
    assert has_site(load_mission(MISSIONS / "site_shapes_3.yaml"))
    assert not has_site(load_mission(MISSIONS / "quickstart.yaml"))
