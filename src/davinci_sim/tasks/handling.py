"""Objects carried by the jaws, the law the kinds with free objects share (peg transfer's
rings, the needle): which instrument holds an object, whether it rests, hand-offs, landings
and drops, for n trials of k objects at once (pure, (n, k) arrays).

* An object is *held* by an instrument when both its jaws touch it (bit ``2·a + j`` of the
  sample's ``grasp`` for jaw ``j`` of instrument ``a``);
* it *rests* when no jaw touches it and its centre has moved slower than ``rest_speed``
  for ``rest_time`` (speeds from consecutive samples: an object just let go is still at the
  first sample without contact);
* its *owner* is the instrument that holds it alone; a *hand-off* is the owner changing
  while it is carried (held since it last rested);
* a carried object that comes to rest *lands* (the kind says where that counts); one that
  comes to rest where it is not ``placed`` (off the pegs, out of the needle's park) is
  *dropped*, once, until it is held again.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class Handling(NamedTuple):
    """The carried objects' state: (n, k) arrays."""

    t_still: np.ndarray
    """Since when the object has been slow and untouched, s (nan: it is not)."""
    owner: np.ndarray
    """1 + index of the instrument that last held it alone (0: none)."""
    carried: np.ndarray
    """Held since it last rested."""
    handed: np.ndarray
    """Handed off since it was picked up."""
    loose: np.ndarray
    """Resting where it is not placed (its drop already counted)."""


class Events(NamedTuple):
    """What happened to each object at a sample: (n, k) arrays."""

    held: np.ndarray
    """Held by an instrument."""
    alone: np.ndarray
    """Held by exactly one instrument."""
    who: np.ndarray
    """1 + index of the first instrument that holds it (meaningful where held)."""
    resting: np.ndarray
    handoff: np.ndarray
    land: np.ndarray
    """A carried object came to rest."""
    handed: np.ndarray
    """Handed off since it was picked up, as it was at this sample (before a landing
    clears it)."""
    drop: np.ndarray


def holders(grasp, instruments: int) -> np.ndarray:
    """(..., A) bool: instrument a holds the object (both its jaws touch it), from the
    jaw bit masks ``grasp`` (...)."""
    g = np.asarray(grasp, dtype=np.int64)
    return ((g[..., None] >> (2 * np.arange(instruments))) & 3) == 3


def handling_step(state: Handling, *, grasp, p, p_prev, t, t_prev, placed, instruments: int,
                  rest_speed: float, rest_time: float) -> tuple[Handling, Events]:  # fmt: skip
    """One sample of n trials of k objects: ``grasp`` (n, k) jaw bits, ``p`` and ``p_prev``
    (n, k, 3) the centres now and at the previous sample (m), ``t`` and ``t_prev`` (n,) s,
    ``placed`` (n, k) where each one is now counts as put where it belongs (not a drop)."""
    grasp = np.asarray(grasp, dtype=np.int64)
    hold = holders(grasp, instruments)
    held = hold.any(axis=-1)
    alone = hold.sum(axis=-1) == 1
    who = np.argmax(hold, axis=-1) + 1
    t = np.asarray(t, dtype=float)[:, None]
    dt = t - np.asarray(t_prev, dtype=float)[:, None]
    step = np.asarray(p, dtype=float) - p_prev
    v2 = np.einsum("...i,...i->...", step, step)
    slow = (grasp == 0) & (v2 < (rest_speed * dt) ** 2) & (dt > 0)
    t_still = np.where(slow, np.where(np.isnan(state.t_still), t, state.t_still), np.nan)
    with np.errstate(invalid="ignore"):
        resting = slow & (t - t_still >= rest_time)

    handoff = state.carried & alone & (state.owner > 0) & (state.owner != who)
    owner = np.where(alone, who, state.owner)
    handed = state.handed | handoff
    carried = state.carried | held
    land = carried & resting
    drop = resting & ~placed & ~state.loose
    loose = np.where(resting, ~placed, state.loose & ~held)
    new = Handling(t_still, np.where(land, 0, owner), carried & ~land, handed & ~land, loose)
    return new, Events(held, alone, who, resting, handoff, land, handed, drop)
