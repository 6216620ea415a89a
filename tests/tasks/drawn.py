"""A task drawn into the one-hand scene, for the tests that it draws visual geoms only."""

import numpy as np

from davinci_sim.model import build_spec


def drawn_visual_only(task, name_prefix: str = "task/"):
    """``task`` drawn into ``psm1_ecm_mtmr``: ``(model, ids)`` of its geoms whose names start
    with ``name_prefix``, after checking that they collide with nothing and that drawing
    added no degree of freedom."""
    spec = build_spec("psm1_ecm_mtmr")
    plain = spec.compile()
    task.draw(spec)
    model = spec.compile()
    ids = [i for i in range(model.ngeom) if model.geom(i).name.startswith(name_prefix)]
    assert model.nq == plain.nq
    assert np.all(model.geom_contype[ids] == 0) and np.all(model.geom_conaffinity[ids] == 0)
    return model, ids
