"""swarm_common.background_writer: chunks land in order (batched or not), flush and close mean written, a
batch waits for its last chunk or a quiet period, a disk error reaches the owner, and the owner does not wait
for a slow disk."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from swarm_common.background_writer import (
    MAX_CHUNKS_PER_HAND_OVER,
    ROWS_PER_HAND_OVER,
    BackgroundWriter,
    chunks_for_rows,
)


@settings(max_examples=30, deadline=None)
@given(chunks=st.lists(st.binary(max_size=5000), max_size=40))
def test_chunks_land_in_order(tmp_path_factory: pytest.TempPathFactory, chunks: list[bytes]) -> None:
    path = tmp_path_factory.mktemp("w") / "log.bin"
    with BackgroundWriter(path, "test") as writer:
        for chunk in chunks:
            writer.write(chunk)
    assert path.read_bytes() == b"".join(chunks)


def test_flush_means_in_the_file(tmp_path: Path) -> None:
    path = tmp_path / "log.bin"
    writer = BackgroundWriter(path, "test")
    try:
        writer.write(b"abc")
        writer.write(b"def")
        writer.flush()
        assert path.read_bytes() == b"abcdef"
    finally:
        writer.close()
    writer.close()  # idempotent
    with pytest.raises(ValueError, match="write after close"):
        writer.write(b"x")


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs /dev/full (Linux)")
def test_a_disk_error_reaches_the_owner() -> None:
    writer = BackgroundWriter(Path("/dev/full"), "test")  # every write: ENOSPC
    writer.write(b"x" * 100)
    with pytest.raises(OSError, match="No space left"):
        writer.flush()
    writer.write(b"more")  # the error was raised once; later chunks are dropped, not written half
    writer.close()


def test_the_owner_does_not_wait_for_the_disk(tmp_path: Path) -> None:
    """The write system calls happen in the writer's thread: while one is held (here: on an event), the
    owner's writes still return."""
    writer = BackgroundWriter(tmp_path / "log.bin", "test")
    entered, release = threading.Event(), threading.Event()
    callers: list[threading.Thread] = []
    real_write = writer._file.write

    def held_write(data: memoryview) -> int:
        callers.append(threading.current_thread())
        entered.set()
        release.wait(timeout=5)
        return real_write(data)

    writer._file.write = held_write  # type: ignore[method-assign]
    writer.write(b"first")
    for _ in range(100):
        writer.write(b"more")
    assert entered.wait(timeout=5) and not release.is_set()  # the first write is held, the owner went on
    release.set()
    writer.close()
    assert callers and all(thread is not threading.main_thread() for thread in callers)
    assert (tmp_path / "log.bin").read_bytes() == b"first" + b"more" * 100


@settings(max_examples=30, deadline=None)
@given(
    chunks=st.lists(st.binary(min_size=1, max_size=300), max_size=60),
    batch=st.integers(1, 8),
    period_s=st.sampled_from([0.001, 0.01, 60.0]),
)
def test_batched_chunks_land_in_order(
    tmp_path_factory: pytest.TempPathFactory, chunks: list[bytes], batch: int, period_s: float
) -> None:
    """Hand-overs by the owner (full batches) and by the thread (after a quiet period) keep the order."""
    path = tmp_path_factory.mktemp("w") / "log.bin"
    with BackgroundWriter(path, "test", chunks_per_hand_over=batch, period_s=period_s) as writer:
        for k, chunk in enumerate(chunks):
            writer.write(chunk)
            if k % 7 == 0:
                time.sleep(0.002)
    assert path.read_bytes() == b"".join(chunks)


def test_a_batch_waits_for_its_last_chunk(tmp_path: Path) -> None:
    path = tmp_path / "log.bin"
    with BackgroundWriter(path, "test", chunks_per_hand_over=3, period_s=60.0) as writer:
        writer.write(b"a")
        writer.write(b"b")
        time.sleep(0.05)
        assert path.read_bytes() == b""  # two of three: still with the owner
        writer.write(b"c")
        deadline = time.monotonic() + 5.0
        while path.read_bytes() != b"abc" and time.monotonic() < deadline:
            time.sleep(0.005)
        assert path.read_bytes() == b"abc"  # the third handed the batch over, no flush needed
        writer.write(b"d")
        writer.flush()
        assert path.read_bytes() == b"abcd"


def test_a_quiet_owner_loses_at_most_a_period(tmp_path: Path) -> None:
    """Chunks of an unfinished batch reach the file once the thread has had nothing for a period: a killed
    process loses at most that."""
    path = tmp_path / "log.bin"
    with BackgroundWriter(path, "test", chunks_per_hand_over=1000, period_s=0.05) as writer:
        started = time.monotonic()
        writer.write(b"lonely")
        while path.read_bytes() != b"lonely" and time.monotonic() - started < 5.0:
            time.sleep(0.005)
        assert path.read_bytes() == b"lonely"


def test_chunks_for_rows() -> None:
    assert (ROWS_PER_HAND_OVER, MAX_CHUNKS_PER_HAND_OVER) == (200, 10)  # the values the cases below assume
    assert chunks_for_rows(200) == 1
    assert chunks_for_rows(2000) == 1
    assert chunks_for_rows(199) == 2
    assert chunks_for_rows(40) == 5
    assert chunks_for_rows(21) == 10
    assert chunks_for_rows(6) == 10  # 34 wanted: capped
    assert chunks_for_rows(0) == 10
    with pytest.raises(ValueError, match="chunks_per_hand_over"):
        BackgroundWriter(Path("/dev/null"), "test", chunks_per_hand_over=0)
