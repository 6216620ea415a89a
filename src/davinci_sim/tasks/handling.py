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

from davinci_sim.kinematics import jit as jit_module
from davinci_sim.kinematics.jit import jit


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
    ``placed`` (n, k) where each one is now counts as put where it belongs (not a drop).

    Compiled (:func:`handling_rows`, each object of each trial in a loop; a live session
    steps one trial a tick); :func:`handling_step_arrays` is the same law in numpy, the
    tests' oracle, bit for bit."""
    grasp = np.asarray(grasp, dtype=np.int64)
    n, k = grasp.shape
    f = lambda a, dtype: np.ascontiguousarray(a, dtype=dtype)  # noqa: E731
    new = Handling(np.empty((n, k)), np.empty((n, k), dtype=np.int64),
                   *(np.empty((n, k), dtype=bool) for _ in range(3)))  # fmt: skip
    e = Events(np.empty((n, k), dtype=bool), np.empty((n, k), dtype=bool),
               np.empty((n, k), dtype=np.int64),
               *(np.empty((n, k), dtype=bool) for _ in range(5)))  # fmt: skip
    handling_rows(
        f(state.t_still, float), f(state.owner, np.int64), f(state.carried, bool),
        f(state.handed, bool), f(state.loose, bool), grasp, f(p, float), f(p_prev, float),
        f(np.reshape(t, -1), float), f(np.reshape(t_prev, -1), float), f(placed, bool),
        int(instruments), float(rest_speed), float(rest_time), *new, *e,
    )  # fmt: skip
    return new, e


@jit
def handling_rows(t_still, owner, carried, handed, loose, grasp, p, p_prev, t, t_prev, placed,
                  instruments, rest_speed, rest_time, t_still_out, owner_out, carried_out,
                  handed_out, loose_out, held, alone, who, resting, handoff, land, handed_now,
                  drop):  # fmt: skip
    """:func:`handling_step` of (n, k) objects into the ``*_out`` state and the events (see
    :class:`Handling`, :class:`Events`; the same bits as :func:`handling_step_arrays`)."""
    n, k = grasp.shape
    for i in range(n):
        dt = t[i] - t_prev[i]
        limit = rest_speed * dt
        for j in range(k):
            g = grasp[i, j]
            holders_, first = 0, 0
            for a in range(instruments):
                if ((g >> (2 * a)) & 3) == 3:
                    holders_ += 1
                    if first == 0:
                        first = a + 1
            is_held, is_alone = holders_ > 0, holders_ == 1
            w = first if first > 0 else 1  # (argmax of no holder: the first)
            dx, dy, dz = p[i, j, 0] - p_prev[i, j, 0], p[i, j, 1] - p_prev[i, j, 1], (
                p[i, j, 2] - p_prev[i, j, 2])  # fmt: skip
            v2 = (dx * dx + dy * dy) + dz * dz
            slow = g == 0 and v2 < limit * limit and dt > 0
            ts = np.nan
            if slow:
                ts = t[i] if np.isnan(t_still[i, j]) else t_still[i, j]
            rests = slow and t[i] - ts >= rest_time
            hand = carried[i, j] and is_alone and owner[i, j] > 0 and owner[i, j] != w
            own = w if is_alone else owner[i, j]
            was_handed = handed[i, j] or hand
            carry = carried[i, j] or is_held
            lands = carry and rests
            drop[i, j] = rests and not placed[i, j] and not loose[i, j]
            loose_out[i, j] = (not placed[i, j]) if rests else (loose[i, j] and not is_held)
            t_still_out[i, j] = ts
            owner_out[i, j] = 0 if lands else own
            carried_out[i, j] = carry and not lands
            handed_out[i, j] = was_handed and not lands
            held[i, j], alone[i, j], who[i, j], resting[i, j] = is_held, is_alone, w, rests
            handoff[i, j], land[i, j], handed_now[i, j] = hand, lands, was_handed


def handling_step_arrays(state: Handling, *, grasp, p, p_prev, t, t_prev, placed,
                         instruments: int, rest_speed: float,
                         rest_time: float) -> tuple[Handling, Events]:  # fmt: skip
    """:func:`handling_step` in numpy (the tests' oracle)."""
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


def _warm_up() -> None:
    """Compile (or load from numba's cache) at import with the callers' one signature."""
    off = np.zeros((1, 1), dtype=bool)
    state = Handling(np.full((1, 1), np.nan), np.zeros((1, 1), dtype=np.int64), off, off, off)
    handling_step(state, grasp=np.zeros((1, 1), dtype=np.int64), p=np.zeros((1, 1, 3)),
                  p_prev=np.zeros((1, 1, 3)), t=np.zeros(1), t_prev=np.zeros(1), placed=off,
                  instruments=2, rest_speed=0.01, rest_time=0.1)  # fmt: skip


jit_module.warm(_warm_up)
