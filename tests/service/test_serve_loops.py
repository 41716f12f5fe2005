"""`gyrosim serve` on a scene with a closed loop: the Bricard mechanism (IFToMM A04, embedded scene ``iftomm_a04``).

Every body of the mechanism publishes its tf (parent -> body) as in any tree; composed down the tree, the published
frames close the loop: rod5's end P5 lands on the ground point (0, 0, 1) m to round-off at every published time,
and each body's composed origin is an independent :class:`gyrosim.model.Model`'s ``r_world`` of the same scene
stepped with the service's step. Real Zenoh sessions on 127.0.0.1 with scouting off (``Served``: the service in a
thread of this process).
"""

import numpy as np
import zenoh
from svc_helpers import reap, wait_until  # noqa: F401 - reap is an autouse fixture
from test_service_inputs import Served

from gyrosim.core.rotations import quat_to_matrix
from gyrosim.model import Model
from gyrosim.service import keys as K
from gyrosim.telemetry import messages as msg

RODS = ("rod1", "rod2", "rod3", "rod4", "rod5")


def _collect(sub, got: dict) -> None:
    for sample in iter(sub.try_recv, None):
        got.setdefault(str(sample.key_expr), []).append(sample.payload.to_bytes())


def test_the_bricard_frames_close_the_loop():
    """0.3 s at 50 Hz: the composed tf of rod5 puts P5 on (0, 0, 1) m to 1e-12 m (the loop's projection keeps it at
    1e-16; the composition of five transforms adds round-off of 1 m links), and every body's composed origin equals
    the model's r_world to 1e-12 m."""
    rate, duration = 50.0, 0.3
    n = int(round(rate * duration)) + 1
    model = Model("iftomm_a04")
    ref = [model.outputs()]
    for _ in range(n - 1):
        model.step(1.0 / rate)
        ref.append(model.outputs())
    with Served("iftomm_a04", rate=rate, realtime_factor=0, duration=duration, wait_subscribers=20) as s:
        sub = s.session.declare_subscriber("gyrosim/iftomm_a04/**", zenoh.handlers.FifoChannel(100_000))
        got: dict = {}
        keys = {b: K.BodyKeys("iftomm_a04", b).tf for b in RODS}
        wait_until(lambda: (_collect(sub, got), all(len(got.get(k, ())) >= n for k in keys.values()))[1],
                   timeout=60, what=f"{n} tf messages of every rod")
    assert s.result["stats"].steps == n - 1
    for k in range(n):
        pose = {"world": (np.eye(3), np.zeros(3))}
        for b in RODS:   # parents before children: the scene's order
            (tr,) = msg.decode_cdr(msg.TF_TYPE, got[keys[b]][k]).transforms
            R_p, o_p = pose[tr.header.frame_id]
            t, q = tr.transform.translation, tr.transform.rotation
            R = quat_to_matrix(np.array([q.w, q.x, q.y, q.z]))
            pose[b] = (R_p @ R, o_p + R_p @ np.array([t.x, t.y, t.z]))
            origin = np.array([ref[k][f"{b}.r_world_{c}"] for c in "xyz"])
            assert np.max(np.abs(pose[b][1] - origin)) < 1e-12, (k, b)
        R5, o5 = pose["rod5"]
        p5 = o5 + R5 @ np.array([0.0, 1.0, 0.0])
        assert np.max(np.abs(p5 - [0.0, 0.0, 1.0])) < 1e-12, (k, p5)
    moved = np.array([ref[-1][f"rod4.r_world_{c}"] for c in "xyz"]) - [1.0, -1.0, 1.0]
    assert np.linalg.norm(moved) > 0.05   # the mechanism moved while it was served
