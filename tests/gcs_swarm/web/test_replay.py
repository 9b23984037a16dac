"""The page's messages built from a hand-written run folder (conftest.py): every expected value is read off
the rows written there, or worked out by hand from them in a comment."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from gcs_swarm.cli import main
from gcs_swarm.web.replay import RunFolderError, event_kind, load_replay


def test_the_scene_holds_the_site_the_vehicles_and_the_events_in_time_order(run_dir: Path) -> None:
    scene = load_replay(run_dir).scene()
    assert scene["type"] == "scene" and scene["mission"] == "quickstart"
    assert scene["vehicles"] == ["lead", "right", "left"]
    assert scene["obstacles"] == [
        {"x": 60, "y": 47, "r": 4},
        {"x": 75, "y": 50, "r": 3},
        {"x": 110, "y": 88, "r": 3},
    ]
    assert scene["prisms"] == [{"name": "block", "footprint": [[20, 60], [30, 60], [30, 70], [20, 70]]}]
    assert scene["cylinders"] == [{"name": "mast", "x": 40, "y": -20, "r": 2}]
    assert scene["fence"]["polygon"] == [[-60, -60], [220, -60], [220, 200], [-60, 200]]
    assert scene["fence"]["exclusions"] == [{"name": "pond", "x": 150, "y": 20, "r": 5}]
    assert scene["goal"] == [160, 120] and scene["waypoints"] == [[160, 120]]
    assert (scene["replay"], scene["t0"], scene["t1"]) == (True, 0.0, 2.0)
    # the fence polygon is the outermost thing (-60..220, -60..200), 10 m of margin around it
    assert scene["bounds"] == [-70, -70, 230, 210]
    # untimed sentences first, then by time; the lost vehicle and the change of leader added from flight.json
    assert [(e["t"], e["kind"]) for e in scene["events"]] == [
        (None, "link"),  # "command mode: ... no link budget"
        (1.2, "reshape"),
        (1.8, "lost"),
        (1.9, "takeover"),
        (1.9, "leader"),
    ]
    assert scene["events"][1]["text"] == "formation narrows: column"
    assert scene["events"][2]["text"] == "left lost" and scene["events"][4]["text"] == "right leads"
    json.dumps(scene, allow_nan=False)  # what the socket sends: plain JSON


def test_a_frame_in_formation_has_slots_phase_modes_and_the_moving_obstacle(run_dir: Path) -> None:
    replay = load_replay(run_dir)
    frame = replay.frame(1)
    assert (frame["t"], frame["phase"], frame["formation"], frame["leader"]) == (1.0, "formation", None, 0)
    lead, right, left = frame["vehicles"]
    assert lead == {
        "x": 1.0, "y": 2.0, "z": 10.0, "yaw": 0.6, "slot": [1.0, 2.0], "mode": "GUIDED", "lost": False,
        "crashed": False,
    }  # fmt: skip
    assert right["slot"] == [-6.0, -5.0] and left["slot"] == [-6.0, 9.0]
    assert (right["x"], right["y"], right["yaw"]) == (-0.5, -8.0, 0.7)
    # the first obstacle moves at (2, -1) m/s from (60, 47): at t = 1 s it is at (62, 46)
    assert frame["obstacles"] == [[62, 46], [75, 50], [110, 88]]
    json.dumps(frame, allow_nan=False)


def test_after_the_record_the_slots_go_and_the_lost_crashed_vehicle_and_new_leader_show(
    run_dir: Path,
) -> None:
    frame = load_replay(run_dir).frame(2)
    # t = 2.0 s is past the last record tick (1.5 s): no slot, no phase known
    assert (frame["t"], frame["phase"], frame["leader"]) == (2.0, None, 1)
    assert frame["formation"] == "formation narrows: column"  # the reshape at 1.2 s is the latest
    assert [v["slot"] for v in frame["vehicles"]] == [None, None, None]
    assert [v["lost"] for v in frame["vehicles"]] == [False, False, True]  # left lost at 1.8 s
    assert [v["crashed"] for v in frame["vehicles"]] == [False, False, True]
    assert [v["mode"] for v in frame["vehicles"]] == ["GUIDED", "GUIDED", "LAND"]
    assert frame["obstacles"][0] == [64, 45]  # (60, 47) + 2 s * (2, -1)


def test_before_the_formation_the_mission_leader_leads_and_nothing_is_recorded_yet(run_dir: Path) -> None:
    frame = load_replay(run_dir).frame(0)
    assert (frame["t"], frame["phase"], frame["leader"]) == (0.0, None, 0)
    assert [v["mode"] for v in frame["vehicles"]] == ["STABILIZE"] * 3
    assert [v["slot"] for v in frame["vehicles"]] == [None] * 3


@pytest.mark.parametrize(
    ("t", "index"), [(-5.0, 0), (0.0, 0), (0.99, 0), (1.0, 1), (1.5, 1), (2.0, 2), (99.0, 2)]
)
def test_a_time_shows_the_last_sample_at_or_before_it(run_dir: Path, t: float, index: int) -> None:
    assert load_replay(run_dir).index_at(t) == index


def test_without_a_truth_log_the_record_gives_positions_and_no_modes(run_dir: Path) -> None:
    (run_dir / "truth.csv").unlink()
    replay = load_replay(run_dir)
    assert replay.source == "record" and replay.t.tolist() == [1.0, 1.5]
    frame = replay.frame(1)
    assert (frame["t"], frame["phase"]) == (1.5, "hold")
    lead = frame["vehicles"][0]
    assert (lead["x"], lead["y"], lead["z"], lead["yaw"], lead["slot"]) == (1.5, 3.0, 10.0, 0.6, [1.5, 3.0])
    assert [v["mode"] for v in frame["vehicles"]] == [None] * 3


def test_event_kinds_by_their_sentences() -> None:
    assert event_kind("formation restored") == "reshape"
    assert event_kind("right rejoins: telemetry fresh again") == "takeover"
    assert event_kind("fence: uploaded to 3 vehicles") == "safety"
    assert event_kind("command mode: attitude targets at 50 Hz, no link budget") == "link"
    assert event_kind("interrupted by the operator") == "note"


def _spoil(run_dir: Path, how: str) -> None:
    """Break the run folder one way."""
    flight = run_dir / "flight.json"
    if how == "no folder":
        for f in run_dir.iterdir():
            f.unlink()
        run_dir.rmdir()
    elif how == "no flight.json":
        flight.unlink()
    elif how == "corrupt flight.json":
        flight.write_text('{"events": [')
    elif how == "flight.json a list":
        flight.write_text("[1, 2]")
    elif how == "bad timeline":
        flight.write_text(
            json.dumps({**json.loads(flight.read_text()), "formation_timeline": [{"t": "soon"}]})
        )
    elif how == "mission gone":
        Path(json.loads(flight.read_text())["mission_path"]).unlink()
    elif how == "no samples":
        (run_dir / "truth.csv").unlink()
        (run_dir / "record.csv").write_text("")
    elif how == "header only":
        (run_dir / "truth.csv").write_text("t,vehicle,x,y,z,yaw,mode,crashed\n")
    elif how == "missing column":
        (run_dir / "truth.csv").write_text("t,vehicle,x,y\n0,0,1,2\n")
    elif how == "garbage numbers":
        (run_dir / "truth.csv").write_text("t,vehicle,x,y,z,yaw,mode,crashed\n0,0,a,b,c,d,e,f\n")
    elif how == "binary truth":
        (run_dir / "truth.csv").write_bytes(b"\xff\xfe\x00garbage\n")


SPOILS = [
    "no folder",
    "no flight.json",
    "corrupt flight.json",
    "flight.json a list",
    "bad timeline",
    "mission gone",
    "no samples",
    "header only",
    "missing column",
    "garbage numbers",
    "binary truth",
]


@pytest.mark.parametrize("how", SPOILS)
def test_a_bad_run_folder_is_one_sentence(run_dir: Path, how: str) -> None:
    _spoil(run_dir, how)
    with pytest.raises(RunFolderError) as caught:
        load_replay(run_dir)
    assert "\n" not in str(caught.value) and str(caught.value)


@pytest.mark.parametrize("how", SPOILS)
@pytest.mark.parametrize("export", [False, True])
def test_the_cli_says_what_is_wrong_with_a_run_folder_in_one_line(
    run_dir: Path, how: str, export: bool, capsys: pytest.CaptureFixture[str]
) -> None:
    _spoil(run_dir, how)
    extra = ["--export", str(run_dir.parent / "out.gif")] if export else ["--port", "0"]
    assert main(["replay", str(run_dir), *extra]) == 2
    out, err = capsys.readouterr()
    assert out.startswith("error: ") and out.count("\n") == 1 and err == ""


def test_a_moved_run_folder_replays_with_the_mission_given(run_dir: Path, tmp_path: Path) -> None:
    mission = Path(json.loads((run_dir / "flight.json").read_text())["mission_path"])
    moved = mission.rename(tmp_path / "elsewhere.yaml")
    with pytest.raises(RunFolderError, match="--mission"):
        load_replay(run_dir)
    assert load_replay(run_dir, moved).scene()["vehicles"] == ["lead", "right", "left"]
