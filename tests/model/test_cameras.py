"""The endoscope's pinhole: the left image's test on one point (what the compiled task ticks
call) is the batch one's, and both are :func:`project_left`'s."""

from __future__ import annotations

import numpy as np

from davinci_sim.model.cameras import (
    CameraConfig,
    in_left_image,
    in_left_image_floats,
    project_left,
)


def test_one_point_and_a_batch_agree_with_the_projection():
    camera = CameraConfig()
    rng = np.random.default_rng(3)
    p = rng.uniform([-0.08, -0.06, -0.02], [0.08, 0.06, 0.15], (4000, 3))
    p[:5] = [(0, 0, 0), (0, 0, 1e-7), (0, 0, -0.05), (0.0025, 0, 0.05), (0, 0, 0.05)]
    batch = in_left_image(p, camera)
    lens = (camera.focal_px, camera.baseline_m / 2.0, float(camera.width), float(camera.height))
    one = [in_left_image_floats(*row, *lens) for row in p.tolist()]
    projected = [project_left(row, camera) for row in p]
    inside = [
        uv is not None and 0 <= uv[0] < camera.width and 0 <= uv[1] < camera.height
        for uv in projected
    ]
    assert list(batch) == one == inside
    assert 0.2 < batch.mean() < 0.8  # (points on both sides of the image's edges)
    assert not batch[:3].any() and batch[3:5].all()  # (behind or at the lens: not seen)
    # (0.0025, 0, 0.05): on the left camera's axis, the image centre
    assert project_left(p[3], camera) == (camera.width / 2.0, camera.height / 2.0)
