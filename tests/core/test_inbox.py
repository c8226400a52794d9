"""The inbox hands items from other threads to the loop: none lost, in order, and a wake-up for an item
already taken is not mistaken for a timeout."""

from __future__ import annotations

import asyncio
import threading

from fleet_emu.core.bus import Inbox


def test_items_from_several_threads_all_arrive_each_thread_in_order() -> None:
    async def go() -> list[tuple[str, bytes, bool]]:
        inbox = Inbox()

        def feed(name: str) -> None:
            for i in range(300):
                inbox.put_nowait((name, i.to_bytes(2, "big"), True))

        threads = [threading.Thread(target=feed, args=(f"t{k}",)) for k in range(4)]
        for t in threads:
            t.start()
        got = []
        while len(got) < 1200:
            item = await inbox.get(timeout=10.0)
            assert item is not None
            got.append(item)
        for t in threads:
            t.join()
        assert await inbox.get(timeout=0.0) is None
        return got

    got = asyncio.run(go())
    for k in range(4):
        seq = [int.from_bytes(d, "big") for key, d, _ in got if key == f"t{k}"]
        assert seq == list(range(300))


def test_a_wake_up_for_an_item_already_taken_does_not_end_the_next_get() -> None:
    async def go() -> tuple[str, bytes, bool] | None:
        inbox = Inbox()
        inbox.put_nowait(("a", b"1", True))  # schedules a wake-up ...
        assert await inbox.get() == ("a", b"1", True)  # ... but the item is taken without waiting for it
        later = threading.Timer(0.2, inbox.put_nowait, args=(("b", b"2", True),))
        later.start()
        try:
            return await inbox.get(timeout=10.0)  # the stale wake-up runs first: not a timeout
        finally:
            later.join()

    assert asyncio.run(go()) == ("b", b"2", True)


def test_an_item_of_the_quiet_key_schedules_no_wake_up_and_the_next_one_takes_it() -> None:
    async def go() -> None:
        inbox = Inbox()
        inbox.quiet = "obs"

        def put(item: tuple[str, bytes, bool]) -> None:
            t = threading.Thread(target=inbox.put_nowait, args=(item,))
            t.start()
            t.join()

        put(("obs", b"1", True))
        assert not inbox._wake_pending  # queued, and the loop not woken for it
        put(("rx", b"2", True))
        assert inbox._wake_pending
        assert await inbox.get(timeout=10.0) == ("obs", b"1", True)  # that wake-up takes both, in order
        assert await inbox.get(timeout=0.0) == ("rx", b"2", True)
        await asyncio.sleep(0)  # the wake-up runs
        inbox.quiet = None
        put(("obs", b"3", True))
        assert inbox._wake_pending  # no longer quiet: it wakes the loop
        assert await inbox.get(timeout=10.0) == ("obs", b"3", True)

    asyncio.run(go())
