"""What a robot hears in a tick: every envelope of its inbox checked against the team, and the payloads of each
kind decoded together (:func:`~fleet_emu.core.codec.decode_many`: one pass of msgspec over all of a kind's, the
map deltas' cells viewed at once), in the order they came.

At 100 robots a robot hears about 75 beacons and 75 map deltas a tick: decoding each on its own cost more than
the merge it feeds. This decides nothing: a kind whose batch does not pass is decoded message by message
(:func:`~fleet_emu.core.envelope.open_envelope`), which drops and counts exactly what does not validate.
"""

from __future__ import annotations

import operator
from collections.abc import Callable, Sequence
from typing import cast

from fleet_emu.core.codec import Context, Payload, decode_many
from fleet_emu.core.envelope import Envelope, keep_opened, open_envelope, opened
from fleet_emu.core.errors import DecodeError

#: One message heard: its envelope and its decoded payload.
Heard = tuple[Envelope, Payload]


def hear(inbox: Sequence[Envelope], ctx: Context, on_drop: Callable[[str, str], None] | None = None,
         shared: bool = False) -> list[Heard]:
    """The messages of ``inbox`` that validate against ``ctx``, each with its payload, in the order they came;
    each that does not is reported to ``on_drop`` (its key, why; a bad header first, then bad payloads in the order
    they came) and left out. With ``shared`` (the memory
    engine, whose receivers of a broadcast hear one envelope object), each payload decoded is kept on its
    envelope as :func:`~fleet_emu.core.envelope.open_envelope` keeps it, and one kept is used."""
    senders = ctx.senders
    kept = list(inbox)
    if senders is None or not senders.issuperset(map(_src, kept)) or not senders.issuperset(map(_origin, kept)):
        kept = [e for e in kept if _valid(e, ctx, on_drop)]
    kinds = list(map(_kind, kept))
    bodies: list[Payload | None] = [_kept(e, ctx) for e in kept] if shared else [None] * len(kept)
    failed: list[tuple[int, DecodeError]] = []
    for kind in dict.fromkeys(kinds):
        places = [i for i, k in enumerate(kinds) if k == kind and bodies[i] is None]
        if not places:
            continue
        batch = decode_many(kind, [kept[i].payload for i in places], ctx) if len(places) > 1 else None
        if batch is not None:
            for i, decoded in zip(places, batch, strict=True):
                bodies[i] = decoded
                if shared:  # kept as open_envelope, the one-by-one way below, keeps what it opens
                    keep_opened(kept[i], ctx, decoded)
            continue
        for i in places:  # one by one (compact ones expanded): each that does not decode is dropped and counted
            try:
                bodies[i] = open_envelope(kept[i], ctx).body
            except DecodeError as exc:
                failed.append((i, exc))
    for i, why in sorted(failed, key=lambda f: f[0]):  # reported in the order they came
        _drop(on_drop, kept[i], why)
    if None not in bodies:
        return list(zip(kept, cast(list[Payload], bodies), strict=True))
    return [(env, body) for env, body in zip(kept, bodies, strict=True) if body is not None]


_src, _origin, _kind = (operator.attrgetter(name) for name in ("src", "origin", "payload_kind"))


def _kept(env: Envelope, ctx: Context) -> Payload | None:
    """The payload kept on ``env`` for a receiver of the same team and grid (:func:`opened`), or None."""
    msg = opened(env, ctx)
    return msg.body if msg is not None else None


def _valid(env: Envelope, ctx: Context, on_drop: Callable[[str, str], None] | None) -> bool:
    try:
        env.validate(ctx)  # raises, saying why
    except DecodeError as exc:
        _drop(on_drop, env, exc)
        return False
    return True


def _drop(on_drop: Callable[[str, str], None] | None, env: Envelope, exc: DecodeError) -> None:
    if on_drop is not None:
        on_drop(f"radio/{env.payload_kind}", str(exc))
