"""The compiled loop of :class:`~davinci_sim.sim.rows_step.RowStepper` (numba only: imported
by :mod:`davinci_sim.sim.rows_step` once MuJoCo's library is loaded into LLVM's symbols).

Module-level functions, so that numba's on-disk cache keeps them between processes.
"""

from __future__ import annotations

import numba
from numba import types
from numba.extending import intrinsic

import davinci_sim.kinematics.jit  # noqa: F401 (its leaner reference counting, before compiling)

# MuJoCo's ``void mj_step(const mjModel*, mjData*)``, the pointers passed as 64-bit integers
# (the same registers in the x86-64 and AArch64 calling conventions).
mj_step = types.ExternalFunction("mj_step", types.void(types.intp, types.intp))
# ``void mj_getState(const mjModel*, const mjData*, mjtNum* state, int sig)`` and
# ``mj_setState`` (the same arguments): the divergence guard's save and rewind.
mj_get_state = types.ExternalFunction(
    "mj_getState", types.void(types.intp, types.intp, types.intp, types.int32)
)
mj_set_state = types.ExternalFunction(
    "mj_setState", types.void(types.intp, types.intp, types.intp, types.int32)
)
# ``void mj_contactForce(const mjModel*, const mjData*, int id, mjtNum result[6])``: contact
# ``id``'s force in its contact frame (the normal component first).
mj_contact_force = types.ExternalFunction(
    "mj_contactForce", types.void(types.intp, types.intp, types.int32, types.intp)
)


def _pointer(nbtype, what: str):
    """An intrinsic giving a ``nbtype*`` at an integer address (``what``: its docstring)."""

    def at(typingctx, address):
        sig = types.CPointer(nbtype)(types.intp)

        def codegen(context, builder, signature, args):
            return builder.inttoptr(args[0], context.get_value_type(types.CPointer(nbtype)))

        return sig, codegen

    at.__doc__ = what
    return intrinsic(at)


f64_at = _pointer(types.float64, "A ``float64*`` at the integer ``address``.")
i32_at = _pointer(types.int32, "An ``int32*`` at the integer ``address`` (MuJoCo's counters).")


@numba.njit(cache=True, nogil=True)
def step_rows(model, data, address, body, rows, out, ctrl, xfrc, Q, V, QB, QG, XI, gravcomp):
    """For each ``j``: the simulation ``rows[j]`` (``model``, ``data``: C pointers;
    ``address``: its ctrl, xfrc_applied, qpos, qvel, qfrc_bias, qfrc_gravcomp, xipos
    buffers) gets ``ctrl[rows[j]]`` and ``xfrc[rows[j]]`` (at ``body``; none if negative),
    one ``mj_step``, and its state is copied into row ``out[j]`` of ``Q``, ``V``, ``QB``,
    ``QG`` (if ``gravcomp``) and ``XI`` (the body's xipos)."""
    nu, nq, nv = ctrl.shape[1], Q.shape[1], V.shape[1]
    for j in range(rows.shape[0]):
        r, o = rows[j], out[j]
        a = address[r]
        c = numba.carray(f64_at(a[0]), (nu,))
        for k in range(nu):
            c[k] = ctrl[r, k]
        if body >= 0:
            x = numba.carray(f64_at(a[1]), (6 * (body + 1),))
            for k in range(6):
                x[6 * body + k] = xfrc[r, k]
        mj_step(model[r], data[r])
        q = numba.carray(f64_at(a[2]), (nq,))
        for k in range(nq):
            Q[o, k] = q[k]
        v = numba.carray(f64_at(a[3]), (nv,))
        b = numba.carray(f64_at(a[4]), (nv,))
        for k in range(nv):
            V[o, k] = v[k]
            QB[o, k] = b[k]
        if gravcomp:
            g = numba.carray(f64_at(a[5]), (nv,))
            for k in range(nv):
                QG[o, k] = g[k]
        if body >= 0:
            xi = numba.carray(f64_at(a[6]), (3 * (body + 1),))
            for k in range(3):
                XI[o, k] = xi[3 * body + k]
