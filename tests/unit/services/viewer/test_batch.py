"""The live view's pass over waiting messages: the newest fire frame drawn, every one checked."""

from __future__ import annotations

from services.common import bus, keys, rejections
from services.viewer.serve import batch


def _item(key: str, payload: bytes = b"") -> bus.Received:
    return bus.Received(key=key, payload=payload, encoding="")


def test_only_each_vehicles_newest_fire_frame_is_drawn_and_every_frame_is_kept() -> None:
    inbox = bus.Inbox()
    later = [_item(keys.fires("a"), b"1"), _item(keys.decision("a")), _item(keys.fires("b")),
             _item(keys.fires("a"), b"2"), _item(keys.forecast("a")), _item(keys.forecast("a"))]
    for it in later:
        inbox._push(it)
    first = _item(keys.forecast("b"))
    got = batch(inbox, first)
    assert [it for it, _ in got] == [first, *later]  # nothing dropped: each one is checked
    assert [draw for _, draw in got] == [True, False, True, True, True, False, True]


def test_a_skipped_bad_frame_is_still_counted_as_rejected() -> None:
    import foxglove

    from services.viewer.serve import Viewer

    viewer = Viewer(foxglove.Context())
    key = keys.fires("skipped")
    before = sum(rejections.REJECTED.snapshot().get(key, {}).values())
    viewer.handle(_item(key, b"\x08\xff\xff garbage"), draw=False)
    assert sum(rejections.REJECTED.snapshot().get(key, {}).values()) == before + 1
    assert "skipped" not in viewer.vehicles  # checked, not drawn
