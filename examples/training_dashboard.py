"""A trainer's view of a training session over rosbridge (roslibpy only, no ROS installation).

Start a session (``davinci-sim serve --task seed_path --condition B=40``), then run this to
follow it: the phase and repetition as they change, the distance to the path, and a line per
finished repetition with its metrics. ``--reset`` abandons the current repetition first::

    python examples/training_dashboard.py --host 127.0.0.1 --port 9090 --duration 60
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import roslibpy


def describe(state: dict) -> str:
    d = state.get("distance_to_path")
    where = "" if d is None else f", {1e3 * d:.2f} mm from the path"
    return (
        f"{state['task']} [{state['condition']}] repetition {state['repetition']}: "
        f"{state['phase']}{where}"
    )


def describe_result(row: dict) -> str:
    return (
        f"repetition {row['repetition']} done: deviation {1e3 * row['deviation_error']:.3f} mm, "
        f"{row['completion_time']:.2f} s, path {1e3 * row['path_length']:.1f} mm, "
        f"peak force {row['peak_force']:.2f} N"
    )


def say(line: str) -> None:
    """Print one line in one write: roslibpy calls back from its own thread, and print()
    writes the text and the newline separately (two threads' lines could interleave)."""
    sys.stdout.write(line + "\n")
    sys.stdout.flush()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--host", default="127.0.0.1")
    parser.add_argument("--port", type=int, default=9090)
    parser.add_argument("--duration", type=float, default=60.0, help="seconds to follow")
    parser.add_argument("--reset", action="store_true", help="abandon the current repetition")
    args = parser.parse_args()

    ros = roslibpy.Ros(args.host, args.port)
    ros.run(10)
    last_phase = None

    def on_state(msg: dict) -> None:
        nonlocal last_phase
        state = json.loads(msg["data"])
        key = (state["phase"], state["repetition"])
        if key != last_phase:  # the distance changes all the time: print phase changes
            last_phase = key
            say(describe(state))

    roslibpy.Topic(ros, "/task/state", "std_msgs/String").subscribe(on_state)
    roslibpy.Topic(ros, "/task/results", "std_msgs/String").subscribe(
        lambda msg: say(describe_result(json.loads(msg["data"])))
    )
    if args.reset:
        roslibpy.Topic(ros, "/task/reset", "std_msgs/Empty").publish(roslibpy.Message({}))
        say("reset sent")
    time.sleep(args.duration)
    ros.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
