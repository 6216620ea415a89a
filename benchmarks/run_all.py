"""Run every benchmark; each writes ``benchmarks/results/<name>.json``."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_bridge  # noqa: E402
import bench_class  # noqa: E402
import bench_client_robot  # noqa: E402
import bench_collisions  # noqa: E402
import bench_compat  # noqa: E402
import bench_envs  # noqa: E402
import bench_exercises  # noqa: E402
import bench_kinematics  # noqa: E402
import bench_peg  # noqa: E402
import bench_realtime  # noqa: E402
import bench_recording  # noqa: E402
import bench_records  # noqa: E402
import bench_render  # noqa: E402
import bench_state  # noqa: E402
import bench_stepped  # noqa: E402
import bench_study  # noqa: E402
import bench_study_small  # noqa: E402
import bench_suture  # noqa: E402
import bench_teleop  # noqa: E402
import bench_tick  # noqa: E402
import bench_web  # noqa: E402

if __name__ == "__main__":
    bench_kinematics.main()
    bench_tick.main()
    bench_collisions.main()  # instruments colliding vs apart, ~1 min
    bench_state.main()
    bench_exercises.main()
    bench_peg.main()  # peg transfer, needle pick-up, needle driving: objects' tick, ~2 min
    bench_suture.main()  # the suture pad's cost, both pairs following, ~2 min
    bench_render.main()
    bench_bridge.main()
    bench_client_robot.main()  # client mode's robot on the remote, ~20 s
    bench_compat.main()  # dVRK scripts' API over both transports, ~30 s
    bench_teleop.main()
    bench_records.main()
    bench_recording.main()  # MCAP recording and replay, ~1 min
    bench_envs.main()  # the learning environments, N = 1, 64, 256 and images, ~2 min
    bench_study.main()  # the 400-trial study, about 2 min
    bench_study_small.main()  # 1 and 16 trials of the seed task, ~2 min (cold compile incl.)
    bench_realtime.main()  # 60 s of real time (plus warm-up)
    bench_web.main()  # the web console, one page drawing the endoscope, 2 x 10 s
    bench_web.main(task="needle_drive")  # the same serving the needle and the suture pad
    bench_stepped.main()  # a script at the page of serve --stepped: a look's cost, ~1 min
    bench_class.main()  # davinci-sim class: 1, 2, ... trainees until one falls behind, ~8 min
