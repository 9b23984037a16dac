"""swarm_common.background_writer: chunks land in order, flush and close mean written, a disk error reaches
the owner, and the owner does not wait for a slow disk."""

from __future__ import annotations

import threading
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from swarm_common.background_writer import BackgroundWriter


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
