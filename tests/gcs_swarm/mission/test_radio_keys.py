"""world.link's radio keys (docs/radio.md): what a valid file gives the simulator, and one error per mistake
naming the file, the line and the key."""

from __future__ import annotations

import pytest

from gcs_swarm.mission import LinkSpec, parse_mission
from swarm_common.radio_presets import RADIO_PRESETS, RadioSpec, radio_spec
from tests.gcs_swarm.mission.test_mission import MINIMAL, error_of


def test_a_preset_and_its_overrides_reach_the_world_as_written() -> None:
    text = MINIMAL + "world:\n  link:\n    radio: sik64\n    buffer_bytes: 1024\n    half_duplex: false\n"
    link = parse_mission(text).world().link
    assert link == LinkSpec(radio="sik64", buffer_bytes=1024, half_duplex=False)
    # the simulator's radio: the SiK preset with the two figures replaced
    sik = RADIO_PRESETS["sik64"]
    expected = RadioSpec(**{**vars(sik), "buffer_bytes": 1024, "half_duplex": False})
    assert radio_spec(link.radio, {"buffer_bytes": 1024, "half_duplex": False}) == expected


def test_no_radio_keys_is_an_ideal_link_and_capacity_alone_is_a_radio() -> None:
    assert parse_mission(MINIMAL).link == LinkSpec()
    link = parse_mission(MINIMAL + "world: {link: {capacity_bps: 1.0e+6, shared: true}}\n").link
    assert (link.radio, link.capacity_bps, link.shared) == (None, 1e6, True)


@pytest.mark.parametrize(
    ("text", "field", "fragment"),
    [
        (MINIMAL + "world: {link: {radio: sik65}}  # <-\n", "world.link.radio", "did you mean 'sik64'?"),
        (MINIMAL + "world: {link: {radio: 64}}  # <-\n", "world.link.radio", "expected one of 'sik64'"),
        (
            MINIMAL + "world: {link: {shared: true}}  # <-\n",
            "world.link.shared",
            "shared without a radio preset needs capacity_bps",
        ),
        (
            MINIMAL + "world: {link: {capacity_bps: 0}}  # <-\n",
            "world.link.capacity_bps",
            "must be >= 1 bit/s",
        ),
        (
            MINIMAL + "world: {link: {radio: wifi, buffer_bytes: 1.5}}  # <-\n",
            "world.link.buffer_bytes",
            "whole",
        ),
        (
            MINIMAL + "world: {link: {radio: wifi, buffer_bytes: -1}}  # <-\n",
            "world.link.buffer_bytes",
            ">= 0",
        ),
        (
            MINIMAL + "world: {link: {radio: sik64, half_duplex: 1}}  # <-\n",
            "world.link.half_duplex",
            "true or",
        ),
        (
            MINIMAL + "world: {link: {radio: sik64, bits_per_byte: 0.5}}  # <-\n",
            "world.link.bits_per_byte",
            ">= 1",
        ),
        (
            MINIMAL + "world: {link: {radio: sik64, capacity: 1}}  # <-\n",
            "world.link.capacity",
            "capacity_bps",
        ),
    ],
)
def test_each_radio_mistake_names_file_line_and_key(text: str, field: str, fragment: str) -> None:
    line = next(i for i, content in enumerate(text.splitlines(), 1) if "# <-" in content)
    message = error_of(text, "missions/bad.yaml")
    assert message.startswith(f"missions/bad.yaml:{line}: {field}: "), message
    assert fragment in message, message
