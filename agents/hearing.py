"""What a robot hears in a tick: its inbox's envelopes checked against the team, and each kind's payloads
decoded together (:func:`~fleet_emu.core.codec.decode_many`; at 100 robots a robot hears about 75 beacons and
75 map deltas a tick). A kind whose batch does not pass is decoded message by message
(:func:`~fleet_emu.core.envelope.open_envelope`), which drops and counts exactly what does not validate."""

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
    each that does not is reported to ``on_drop`` (its key, why: bad headers, then bad payloads in the order
    they came) and left out. With ``shared`` (the memory engine: a broadcast is one envelope object), a payload
    is kept on its envelope as :func:`~fleet_emu.core.envelope.open_envelope` keeps it, and one kept is used."""
    senders = ctx.senders
    kept = list(inbox)
    if senders is None or not senders.issuperset(map(_src, kept)) or not senders.issuperset(map(_origin, kept)):
        kept = [e for e in kept if _valid(e, ctx, on_drop)]
    bodies: list[Payload | None] = ([getattr(opened(e, ctx), "body", None) for e in kept] if shared
                                    else [None] * len(kept))
    places: dict[str, list[int]] = {}  # each kind's envelopes still to decode, in the order they came
    for i, kind in enumerate(map(_kind, kept)):
        if bodies[i] is None:
            places.setdefault(kind, []).append(i)
    failed: list[tuple[int, DecodeError]] = []
    for kind, these in places.items():
        batch = decode_many(kind, [kept[i].payload for i in these], ctx) if len(these) > 1 else None
        if batch is not None:
            for i, decoded in zip(these, batch, strict=True):
                bodies[i] = decoded
                if shared:  # kept as open_envelope, the one-by-one way below, keeps what it opens
                    keep_opened(kept[i], ctx, decoded)
            continue
        for i in these:  # one by one (compact ones expanded): each that does not decode is dropped and counted
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
