"""The ``davinci-sim`` command line: ``info``, ``urdf``, ``snapshot``, ``demo``, ``serve``,
``replay``, ``run``, ``task``, ``trainees`` and ``study``.

Size: over 500 lines because the command line is one parser: each command is a short
function that checks its options and calls the package, and ``serve`` alone has some forty
options (the rosbridge server, UDP, client mode, the task, the web console); splitting the
parser would scatter the one place a user's options are declared and checked.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path

import numpy as np


def _scene_names() -> list[str]:
    from davinci_sim.model import SCENES

    return list(SCENES)


def _home_all(sim, timeout: float = 30.0) -> bool:
    """Enable and home every arm; tick until none is busy. True if all homed in time."""
    for arm in sim.arms.values():
        arm.state_command("enable")
        arm.state_command("home")
    return sim.run_until(
        lambda: all(a.is_homed() and not a.is_busy() for a in sim.arms.values()), timeout
    )


def cmd_info(args: argparse.Namespace) -> int:
    from davinci_sim.kinematics.arms import ARM_FILES, load_arm, load_suj
    from davinci_sim.model import SCENES

    print("Arms (dVRK kinematics, dvrk.md section 1):")
    for name in ARM_FILES:
        kin = load_arm(name)
        extra = kin.jaw or kin.gripper
        print(f"  {name:5s} {kin.arm_type}  {kin.chain.convention} DH, {kin.dof} joints")
        for j in kin.chain.joints:
            unit = "m" if j.joint_type == "prismatic" else "rad"
            print(f"        {j.name:15s} [{j.qmin:+.4f}, {j.qmax:+.4f}] {unit}")
        if extra:
            print(f"        {extra.name:15s} [{extra.qmin:+.4f}, {extra.qmax:+.4f}] rad")
    print("Setup joints:", ", ".join(f"SUJ/{n}" for n in load_suj()))
    print("Scenes:")
    for name, cfg in SCENES.items():
        print(f"  {name:16s} arms: {', '.join(cfg.arms)}")
    return 0


def cmd_urdf(args: argparse.Namespace) -> int:
    from davinci_sim.model.urdf import scene_robot

    robot = scene_robot(args.scene)
    if args.arm is not None:
        try:
            robot = robot.arm(args.arm)
        except KeyError:
            print(f"davinci-sim urdf: no arm {args.arm!r} in scene {args.scene!r}; its arms: "
                  f"{', '.join(robot.arms)}", file=sys.stderr)  # fmt: skip
            return 2
    text = robot.to_xml()
    if args.output is None:
        sys.stdout.write(text)
    else:
        Path(args.output).write_text(text)
    return 0


def cmd_snapshot(args: argparse.Namespace) -> int:
    from PIL import Image

    from davinci_sim.system import SystemDescription, TaskDescription, new_simulation
    from davinci_sim.tasks import TaskError

    task = None if args.task is None else TaskDescription(args.task)
    description = SystemDescription(scene=args.scene, keyframe=args.keyframe, task=task)
    out = Path(args.output)
    if out.exists() and not out.is_dir():  # (said before the scene is built)
        print(f"davinci-sim snapshot: {out} exists and is not a folder; -o names the folder "
              "the PNG files go to", file=sys.stderr)  # fmt: skip
        return 2
    try:
        sim = new_simulation(description)  # the scene with the task's path drawn
    except TaskError as e:
        print(f"davinci-sim snapshot: {e}", file=sys.stderr)
        return 2
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:  # (a parent that is a file, no permission …)
        print(f"davinci-sim snapshot: cannot create the folder {out}: {e.strerror}",
              file=sys.stderr)  # fmt: skip
        return 2
    if not args.no_home:
        _home_all(sim)
    sim.run_for(0.2)
    left, right = sim.render_stereo()
    written = []
    for name, img in (("endoscope_left", left), ("endoscope_right", right)):
        path = out / f"{name}.png"
        Image.fromarray(img).save(path)
        written.append(path)
    path = out / "overview.png"
    Image.fromarray(sim.render("overview", 1280, 960)).save(path)
    written.append(path)
    sim.close()
    for p in written:
        print(p)
    return 0


def _demo(sim, log) -> dict:
    """Scripted motion of every PSM and the ECM; returns what happened."""
    report: dict = {}
    t0 = time.perf_counter()
    ok = _home_all(sim)
    log(
        f"enable + home of {len(sim.arms)} arms: {'done' if ok else 'TIMEOUT'} "
        f"at t={sim.time:.2f} s"
    )
    report["homed"] = ok
    psms = [n for n in ("PSM1", "PSM2", "PSM3") if n in sim.arms]
    # 1. move_jp: yaw/pitch out and back, as dvrk_arm_test.py does.
    for name in psms:
        sim.arms[name].move_jr([0.2, -0.15, -0.02, 0.5, 0.3, -0.3])
    if "ECM" in sim.arms:
        sim.arms["ECM"].move_jr([0.1, 0.1, 0.0, 0.2])
    sim.run_until(
        lambda: not any(sim.arms[n].is_busy() for n in [*psms, "ECM"] if n in sim.arms), 20
    )
    log(f"move_jr of the PSMs and the ECM finished at t={sim.time:.2f} s")
    # 2. servo_cp: a 2 cm circle of each PSM tip in the camera frame, 2 s, jaw opening.
    errors = {n: 0.0 for n in psms}
    starts = {n: sim.arms[n].setpoint_cp().T.copy() for n in psms}
    for name in psms:
        sim.arms[name].jaw.move_jp(np.radians(45))
    steps = 2000
    for k in range(steps):
        s = 2 * np.pi * k / steps
        offset = 0.02 * np.array([np.sin(s), 1 - np.cos(s), 0.0])
        # Velocity feed-forward, as the dVRK teleoperation sends with servo_cp (dvrk.md 4.2).
        velocity = 0.02 * 2 * np.pi / (steps * sim.dt) * np.array([np.cos(s), np.sin(s), 0.0])
        for name in psms:
            goal = starts[name].copy()
            goal[:3, 3] += offset
            sim.arms[name].servo_cp(goal, twist=np.r_[velocity, 0.0, 0.0, 0.0])
        sim.tick()
        for name in psms:
            err = np.linalg.norm(
                sim.arms[name].measured_cp().position - starts[name][:3, 3] - offset
            )
            if k >= 200:  # after the start-up transient of 0.2 s
                errors[name] = max(errors[name], err)
    log(
        "servo_cp circle (r = 2 cm, 2 s, velocity feed-forward): max tip error "
        + ", ".join(f"{n} {1000 * e:.2f} mm" for n, e in errors.items())
    )
    for name in psms:
        sim.arms[name].jaw.move_jp(0.0)
    sim.run_until(lambda: not any(sim.arms[n].is_busy() for n in psms), 5)
    # 3. ECM moves the camera: the PSM tips move in the camera frame while they hold.
    if "ECM" in sim.arms and psms:
        before = sim.arms[psms[0]].measured_cp().position.copy()
        sim.arms["ECM"].move_jr([0.15, 0.0, 0.0, 0.0])
        sim.run_until(lambda: not sim.arms["ECM"].is_busy(), 10)
        sim.run_for(0.3)
        after = sim.arms[psms[0]].measured_cp().position
        log(
            f"ECM yaw +0.15 rad: {psms[0]} tip moved "
            f"{1000 * np.linalg.norm(after - before):.1f} mm in the camera frame "
            "(the camera moved, the tool held)"
        )
    # 4. A refused command: the arm keeps its setpoint and the simulation carries on.
    if psms:
        arm = sim.arms[psms[0]]
        before = arm.setpoint_jp()
        result = arm.servo_jp([np.nan] * 6)
        log(f"bad command refused: {result.message}")
        report["refused_ok"] = (not result.accepted) and np.array_equal(before, arm.setpoint_jp())
    wall = time.perf_counter() - t0
    report["sim_time_s"] = sim.time
    report["wall_time_s"] = wall
    log(f"simulated {sim.time:.2f} s in {wall:.2f} s wall time ({sim.time / wall:.1f}x real time)")
    for name, arm in sim.arms.items():
        st = arm.operating_state()
        line = f"  {name:9s} {st.state:8s} homed={st.is_homed!s:5s}"
        if arm.kin.arm_type in ("PSM", "ECM", "MTM"):
            cp = arm.measured_cp()
            p = cp.position
            line += f" tip ({p[0]:+.4f}, {p[1]:+.4f}, {p[2]:+.4f}) m in {cp.reference_frame}"
        log(line)
    return report


def cmd_demo(args: argparse.Namespace) -> int:
    from davinci_sim.system import SystemDescription, build_system

    # No runner: the demo ticks the simulation itself, as fast as it computes.
    description = SystemDescription(
        scene=args.scene, keyframe=args.keyframe, seed=args.seed, runner="none"
    )
    system = build_system(description)
    try:
        report = _demo(system.sim, print)
    finally:
        system.stop()
    return 0 if report["homed"] and report.get("refused_ok", True) else 1


def serve_scene(args: argparse.Namespace):
    """``serve``'s scene: the name, or its :class:`~davinci_sim.model.config.SceneConfig` with
    the robot inaccuracy of ``--joint-errors``/``--random-joint-errors``. ValueError for
    errors that cannot be."""
    from davinci_sim.model.config import parse_joint_errors, random_joint_errors, resolve_scene

    errors = parse_joint_errors(getattr(args, "joint_errors", None) or [])
    seed = getattr(args, "random_joint_errors", None)
    if seed is not None:
        if errors:
            raise ValueError("--joint-errors and --random-joint-errors: give one of them")
        errors = random_joint_errors(resolve_scene(args.scene).arms, seed)
    if not errors:
        return args.scene
    return resolve_scene(args.scene, joint_errors=errors)


def serve_options(args: argparse.Namespace, web: bool):
    """The :class:`~davinci_sim.bridge.app.ServeOptions` of ``serve``'s parsed ``args``
    (``web``: with the web console), as ``cmd_serve`` runs them; the browser test of
    ``make run`` serves these through :func:`serve_setup`."""
    from davinci_sim.bridge.app import ServeOptions
    from davinci_sim.bridge.rosbridge.config import BridgeConfig
    from davinci_sim.bridge.udp import parse_ports

    runner = args.runner or ("process" if web else "thread")
    if args.stepped and not web:
        raise ValueError("--stepped: the web console's pages advance the simulation; drop --no-web")
    if args.stepped and runner != "process":
        raise ValueError("--stepped runs the loop in its own process: drop --runner thread")
    # The console and pedals (/console/*, /footpedals/*) by default, as the dVRK's system
    # serves them, whenever the scene has an MTM and a PSM to teleoperate.
    console = args.task is not None or (
        not args.no_console and (args.console or _scene_has_teleop(args.scene))
    )
    # The web console's keyboard hands only when the console is asked for: a simulated hand
    # holds the MTM handle, which scripts commanding the MTM would fight.
    asked = args.console or args.task is not None
    hands = ("MTML", "MTMR") if web and asked and args.ros_connect is None else ()
    return ServeOptions(
        scene=serve_scene(args),
        keyframe=args.keyframe,
        seed=args.seed,
        real_time=not (args.fast or args.stepped),
        stepped=args.stepped,
        home=args.home,
        server=not args.no_server,
        bridge=BridgeConfig(
            host=args.host,
            port=args.port,
            ros_version=args.ros_version,
            max_message_size=args.max_message_size,
            auth_token=_serve_token(args),
            stamp_clock=args.stamps,
        ),
        rate=args.rate,
        tf_rate=args.tf_rate,
        images=args.images,
        image_rate=args.image_rate,
        rig=args.rig,
        udp=args.udp,
        udp_ports=parse_ports(args.udp_ports),
        udp_ip=args.udp_ip,
        ros_connect=args.ros_connect,
        namespace=args.namespace,
        remote_ros_version=args.remote_ros_version,
        robot_description=not args.no_robot_description,
        duration=args.duration,
        console=console,
        runner=runner,
        hand_inputs=hands,
        render_hz=args.image_rate if web else None,
        frame_task=web,
        realtime_priority=args.realtime_priority,
        task=args.task,
        condition=args.condition,
        task_log=args.task_log,
        record_inputs=args.record is not None,
    )


def web_options(args: argparse.Namespace):
    """The web console's :class:`~davinci_sim.web.server.WebOptions` of ``serve``'s ``args``."""
    from davinci_sim.web.server import WebOptions

    return WebOptions(host=args.host, port=args.web_port, token=_serve_token(args),
                      frame_rate=args.image_rate)  # fmt: skip


def _serve_token(args: argparse.Namespace) -> str | None:
    """``serve``'s token: ``--token`` or ``$DAVINCI_SIM_TOKEN`` (None: none)."""
    return args.token or os.environ.get("DAVINCI_SIM_TOKEN") or None


def serve_setup(args: argparse.Namespace, web: bool, on_exercise=None) -> tuple:
    """``serve``'s options (:func:`serve_options`) and its parts (trainee records, the web
    console, a recording) from its parsed ``args``, every input checked before anything
    starts; the browser test of ``make run`` serves exactly these. ``on_exercise``: the
    call with which the page switches to another shipped exercise (None: it cannot).

    Raises:
        ValueError: a bad task, condition or records file (TaskError and RecordsError).
        OSError: a recording or records file that cannot be created.
    """
    parts: list = []
    records = None
    if args.task is not None and not args.no_records:  # every attempt recorded
        from davinci_sim.records import records_part

        records = records_part(args.trainee or DEFAULT_TRAINEE, path=args.records,
                               task=args.task, condition=args.condition)  # fmt: skip
    if web:
        from davinci_sim.tasks.base import available_tasks
        from davinci_sim.web.app import web_part

        exercises = tuple(available_tasks()) if on_exercise is not None else ()
        parts.append(web_part(web_options(args), bedside=not args.no_bedside, records=records,
                              exercises=exercises, on_exercise=on_exercise))  # fmt: skip
    options = serve_options(args, web)
    if args.record is not None:  # (a file that cannot be created: say so now)
        from davinci_sim.records.recording import recording_part

        Path(args.record).open("ab").close()
        parts.insert(0, recording_part(args.record, args.record_images, args.record_rate))
    if args.task is not None:  # a bad task or condition: say so before starting anything
        from davinci_sim.bridge.app import task_condition
        from davinci_sim.tasks import load_task
        from davinci_sim.tasks.check import task_problem

        task = load_task(args.task)
        task.fixture(task_condition(task, args.condition))  # checks the values too
        problem = task_problem(task)
        if problem is not None:
            raise ValueError(problem)
        if records is not None:  # (an unusable records file: say so now)
            from davinci_sim.records import RecordsDB

            RecordsDB(records.path).close()
            parts.insert(0, records)  # (attached before any page can start a repetition)
    return options, parts


def _class_parser(sub) -> None:
    p = sub.add_parser(
        "class",
        help="a class on one server: a system and a web console per trainee, and a lobby page",
    )
    who = p.add_mutually_exclusive_group(required=True)
    who.add_argument("--trainees", type=int, help="this many trainees (trainee-1, trainee-2 …)")
    who.add_argument("--names", help="the trainees' names, comma-separated")
    p.add_argument("--task", default="seed_path", help="the exercise (name or task file)")
    p.add_argument("--host", default="127.0.0.1", help="interface of the lobby and consoles")
    p.add_argument("--port", type=int, default=8080,
                   help="the lobby's port; trainee k's console is on port + k")  # fmt: skip
    p.add_argument("--token", default=None, help="required beyond loopback (or $DAVINCI_SIM_TOKEN)")
    p.add_argument("--realtime-priority", type=int, default=None, metavar="N",
                   help="SCHED_FIFO priority N of every loop process (as serve's)")  # fmt: skip
    p.add_argument("--records", default=None, metavar="FILE", help=_RECORDS_HELP)
    p.add_argument("--duration", type=float, default=None, help="stop after this many seconds")
    p.add_argument("--ray", default=None, metavar="ADDRESS",
                   help="run the systems on this Ray cluster ('auto': the one this machine "
                   "is in), spread over its nodes")  # fmt: skip
    p.add_argument(
        "--cpus-per-trainee",
        type=float,
        default=1.0,
        metavar="N",
        help="CPUs Ray reserves per system (with --ray; default 1)",
    )
    p.set_defaults(func=cmd_class)


def cmd_class(args: argparse.Namespace) -> int:
    """``davinci-sim class``: start the systems and the lobby; Ctrl-C stops them all."""
    import signal
    import threading

    from davinci_sim.web.classroom import ClassOptions, Classroom

    if args.names is not None:
        names = tuple(n.strip() for n in args.names.split(",") if n.strip())
    else:
        names = tuple(f"trainee-{k + 1}" for k in range(max(0, args.trainees)))
    token = args.token or os.environ.get("DAVINCI_SIM_TOKEN") or None
    try:
        options = ClassOptions(names, task=args.task, host=args.host, port=args.port,
                               token=token, realtime_priority=args.realtime_priority,
                               records=args.records, ray_address=args.ray,
                               cpus_per_trainee=args.cpus_per_trainee)  # fmt: skip
        from davinci_sim.web.server import WebOptions

        WebOptions(host=args.host, token=token)  # (the same rule as serve's: a token off loopback)
    except ValueError as e:
        print(f"davinci-sim class: {e}", file=sys.stderr)
        return 2
    stop = threading.Event()
    signal.signal(signal.SIGINT, lambda *_: stop.set())
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    try:
        room = Classroom(options).start()
    except OSError as e:
        print(f"davinci-sim class: the lobby cannot serve on port {args.port}: {e}",
              file=sys.stderr)  # fmt: skip
        return 2
    except (ImportError, ConnectionError, RuntimeError) as e:  # (Ray missing or unreachable)
        print(f"davinci-sim class: {e}", file=sys.stderr)
        return 2
    print(f"class lobby: {room.url}  <- the trainees open this", flush=True)
    announced: set[str] = set()
    end = None if args.duration is None else time.monotonic() + args.duration
    while not stop.is_set() and (end is None or time.monotonic() < end):
        status = room.status()
        for s in status:
            if s["url"] and s["name"] not in announced:
                announced.add(s["name"])
                where = f" (Ray node {s['node'][:8]})" if s["node"] else ""
                print(f"{s['name']}: {s['url']}{where}", flush=True)
        if all(s["state"].startswith("exited") for s in status):
            break
        stop.wait(0.5)
    print("stopping the class …", flush=True)
    for s in room.stop():
        last = s["notes"][-1] if s["notes"] else ""
        print(f"{s['name']}: {s['state']}; {last}", flush=True)
    return 0


def cmd_serve(args: argparse.Namespace) -> int:
    """The simulation with its ROS interfaces (rosbridge server, UDP, client mode)."""
    import logging
    import signal
    import threading

    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING,
                        format="%(asctime)s %(levelname)s %(name)s: %(message)s")  # fmt: skip
    problem = _serve_option_problem(args)
    if problem is not None:
        print(f"davinci-sim serve: {problem}", file=sys.stderr)
        return 2
    web = not args.no_web
    problem = _taken_port_problem(args, web)
    if problem is not None:  # before the scene is built
        print(f"davinci-sim serve: {problem}", file=sys.stderr)
        return 2
    stop = threading.Event()
    # A page may switch the exercise (--task): serve stops, then starts again with it on the
    # same ports (the pages reconnect). Ctrl-C or SIGTERM stop for good.
    switch: dict = {}

    def on_exercise(name: str) -> str | None:
        if stop.is_set():
            return "the server is stopping"
        switch["task"] = name
        stop.set()
        return None

    def quit_(*_) -> None:
        switch["quit"] = True
        stop.set()

    signal.signal(signal.SIGINT, quit_)
    signal.signal(signal.SIGTERM, quit_)
    while True:
        code = _serve_once(args, web, stop, on_exercise if args.task is not None else None)
        task = switch.pop("task", None)
        if code != 0 or task is None or switch.get("quit"):
            return code
        print(f"switching to the exercise {task} …", flush=True)
        args.task, args.condition = task, None
        stop.clear()


def _serve_once(args: argparse.Namespace, web: bool, stop, on_exercise) -> int:
    """One run of ``serve`` until ``stop`` is set (by a signal, or a page's exercise)."""
    from davinci_sim.bridge.app import serve

    try:
        options, parts = serve_setup(args, web, on_exercise)
    except (ValueError, OSError) as e:  # TaskError and RecordsError are ValueErrors
        print(f"davinci-sim serve: {e}", file=sys.stderr)
        return 2

    def ready(info: dict) -> None:
        if "url" in info:
            print(f"rosbridge server: {info['url']} (ROS {args.ros_version})", flush=True)
        for arm, (ip, port, local) in info.get("udp", {}).items():
            print(f"UDP {arm}: streaming to {ip}:{port}, commands to port {local}", flush=True)
        if "ros_connect" in info:
            print(f"client mode: connected to {info['ros_connect']}", flush=True)
        for psm, e in getattr(options.scene, "joint_errors", ()):
            print(f"robot inaccuracy: {psm} joint errors yaw {math.degrees(e[0]):+.2f} deg, "
                  f"pitch {math.degrees(e[1]):+.2f} deg, insertion {e[2] * 1e3:+.2f} mm",
                  flush=True)  # fmt: skip
        loop = info.get("loop", {})
        if args.realtime_priority is not None:
            if loop.get("realtime_priority"):
                print(f"loop process: SCHED_FIFO priority {args.realtime_priority}", flush=True)
            else:
                why = loop.get("realtime_priority_error", "not a process runner")
                print(f"loop process: normal priority ({why})", flush=True)
        if "recording" in info:
            print(f"recording: {info['recording']}", flush=True)
        if "records" in info:
            print(f"trainee records: {info['records']} (trainee {info['trainee']!r})", flush=True)
        if "web" in info:
            print(f"web console: {info['web']}  <- open this in a browser", flush=True)
        if "bedside" in info:
            print(f"3-D view: {info['bedside']}", flush=True)
        print("ready (Ctrl-C to stop)", flush=True)

    try:
        info = serve(options, stop=stop, on_ready=ready, parts=parts, freeze_heap=True,
                     on_warning=lambda text: print(f"warning: {text}", flush=True))  # fmt: skip
    except OSError as e:  # a port is taken (the rosbridge server's or the web console's)
        problem = _taken_port_problem(args, web)  # (taken meanwhile: say by what, if known)
        print(f"davinci-sim serve: {problem or f'{e}; choose another port (--port, --web-port)'}",
              file=sys.stderr)  # fmt: skip
        return 2
    print(f"stopped; simulation ran at {info.get('sim_over_wall', 0):.3f}x real time", flush=True)
    stats = info.get("period_statistics")
    if stats is not None:
        print(
            f"loop: {stats.achieved_rate_hz:.1f} Hz, p99 period {1000 * stats.period_p99:.2f} ms, "
            f"max {1000 * stats.period_max:.2f} ms",
            flush=True,
        )
    return 0


def _scene_has_teleop(scene: str) -> bool:
    """Whether ``scene`` has an MTM and the PSM it teleoperates (the console's condition)."""
    from davinci_sim.console.setup import PSM_TELEOPS
    from davinci_sim.model.config import scene_arms

    arms = set(scene_arms(scene))
    return any(m in arms and p in arms for m, p in PSM_TELEOPS)


def _serve_option_problem(args: argparse.Namespace) -> str | None:
    """What is wrong with ``serve``'s options that the parser cannot see (None: nothing)."""
    import math

    for name in ("rate", "tf_rate", "image_rate"):
        value = getattr(args, name)
        if not (math.isfinite(value) and value > 0):
            return f"--{name.replace('_', '-')} must be a rate > 0 Hz, got {value:g}"
    if args.duration is not None and not (math.isfinite(args.duration) and args.duration >= 0):
        return f"--duration must be a time >= 0 s, got {args.duration:g}"
    if args.condition is not None and args.task is None:
        return "--condition needs --task (the condition of which task?)"
    try:
        serve_scene(args)
    except ValueError as e:
        return str(e)
    if args.no_console and (args.console or args.task is not None):
        return "--no-console contradicts " + ("--console" if args.console else "--task")
    if args.trainee is not None and args.task is None:
        return "--trainee needs --task (the attempts at which task?)"
    if args.trainee is not None:
        from davinci_sim.records.db import RecordsError, check_name

        try:
            check_name(args.trainee)
        except RecordsError as e:
            return f"--trainee: {e}"
    if args.realtime_priority is not None and not 1 <= args.realtime_priority <= 99:
        return "--realtime-priority must be in 1..99"
    for name in ("port", "web_port"):
        value = getattr(args, name)
        if not 0 <= value <= 65535:
            return f"--{name.replace('_', '-')} must be a port in 0..65535, got {value}"
    if args.ros_connect is not None:
        from davinci_sim.bridge.client_mode import ClientModeConfig

        try:
            ClientModeConfig(args.ros_connect, namespace=args.namespace)
        except ValueError as e:
            return f"--ros-connect/--namespace: {e}"
    return None


def _taken_port_problem(args: argparse.Namespace, web: bool) -> str | None:
    """The first of ``serve``'s ports that is taken, what holds it if that can be known, and
    the option that chooses another (None: all free)."""
    from davinci_sim.bridge.ports import port_holder, port_taken, taken_port_message

    ports = [("--port", args.port)] if not args.no_server else []
    ports += [("--web-port", args.web_port)] if web else []
    for option, port in ports:
        if port_taken(args.host, port):
            return taken_port_message(port, option, port_holder(port))
    return None


def cmd_task_check(args: argparse.Namespace) -> int:
    """Each point of a task: reachable by its PSM, and where the endoscope shows it."""
    from davinci_sim.tasks import TaskError, load_task
    from davinci_sim.tasks.check import check_task

    try:
        task = load_task(args.file if not Path(args.file).suffix else Path(args.file))
        checks = check_task(task)
    except (TaskError, ValueError, OSError) as e:
        print(f"davinci-sim task check: {e}", file=sys.stderr)
        return 2
    arms = " or ".join(getattr(task, "instruments", None) or (task.teleop.psm,))
    print(f"task {task.name!r}: {arms} at keyframe {task.teleop.keyframe!r}, "
          f"left endoscope image")  # fmt: skip
    for c in checks:
        x, y, z = c.p_task
        seen = (
            "behind the camera"
            if c.pixel is None
            else f"pixel ({c.pixel[0]:.0f}, {c.pixel[1]:.0f})"
        )
        turned = "" if c.turned_deg is None else f" (the tool turned {c.turned_deg:.1f}°)"
        print(f"  point {c.index}{turned}: ({x:+.4f}, {y:+.4f}, {z:+.4f}) m  "
              f"{'reachable' if c.reachable else 'UNREACHABLE: ' + c.why}; "
              f"{'in view' if c.in_view else 'OUT OF VIEW'}, {seen}")  # fmt: skip
    bad = sum(not c.ok for c in checks)
    print("ok" if not bad else f"{bad} point(s) fail")
    return 0 if not bad else 1


#: The trainee ``serve --task`` records the attempts of without ``--trainee``.
DEFAULT_TRAINEE = "guest"


def cmd_trainees(args: argparse.Namespace) -> int:
    """The trainee records: list, show, export, curve (see ``davinci_sim.records.report``)."""
    from davinci_sim.records import RecordsDB, RecordsError
    from davinci_sim.records import report as records_report

    where = f"davinci-sim trainees {args.trainees_command}"
    try:
        pass_marks = dict(_pass_mark(text) for text in getattr(args, "pass_mark", None) or ())
        with RecordsDB(args.records, create=False) as db:
            if args.trainees_command == "list":
                print(records_report.list_text(db))
            elif args.trainees_command == "show":
                print(records_report.show_text(db, args.name))
            elif args.trainees_command == "export":
                if args.csv in (None, "-"):
                    records_report.export_csv(db, sys.stdout, args.trainee)
                else:
                    import io

                    buffer = io.StringIO()
                    n = records_report.export_csv(db, buffer, args.trainee)
                    try:
                        Path(args.csv).write_text(buffer.getvalue(), encoding="utf-8")
                    except OSError as e:
                        raise RecordsError(f"cannot write {args.csv}: {e.strerror or e}") from e
                    print(f"{args.csv}: {n} attempt(s)")
            else:
                out = records_report.draw_curves(
                    db, args.name, args.output, task=args.task, metrics=args.metric,
                    pass_marks=pass_marks,
                )  # fmt: skip
                print(out)
    except RecordsError as e:
        print(f"{where}: {e}", file=sys.stderr)
        return 2
    return 0


def _pass_mark(text: str) -> tuple[str, float]:
    """``METRIC=VALUE`` of ``--pass-mark``."""
    import math

    from davinci_sim.records import RecordsError

    name, sep, value = text.partition("=")
    try:
        mark = float(value)
    except ValueError:
        mark = math.nan
    if not sep or not name or not math.isfinite(mark):
        raise RecordsError(f"--pass-mark wants METRIC=VALUE (a finite number), got {text!r}")
    return name, mark


def cmd_study(args: argparse.Namespace) -> int:
    from davinci_sim.study import StudyConfig, StudyError, parse_conditions
    from davinci_sim.study.config import parse_fixture

    out = Path(args.output)
    if out.exists() and not out.is_dir():  # say so before hours of trials, not after
        print(f"davinci-sim study: the output {out} exists and is not a folder", file=sys.stderr)
        return 2
    from davinci_sim.study.console_trial import CONSOLE_KINDS
    from davinci_sim.tasks import TaskError, load_task
    from davinci_sim.tasks.check import task_problem

    try:  # the task, loaded and checked here, before any worker starts
        task = load_task(args.task if not Path(args.task).suffix else Path(args.task))
        if task.kind not in ("path", *CONSOLE_KINDS):
            problem = (f"task {task.name!r} is a {task.kind} exercise; the study's synthetic "
                       f"trainees do path tasks and {', '.join(CONSOLE_KINDS)}")  # fmt: skip
        else:
            problem = task_problem(task)
    except (TaskError, ValueError, OSError) as e:
        problem = str(e)
    if problem is not None:
        print(f"davinci-sim study: {problem}", file=sys.stderr)
        return 2
    if args.engine is None:  # (a needle exercise's trainees run on the live engine only)
        args.engine = "batch" if task.kind == "path" else "live"
    if args.record is not None and args.engine != "batch":
        print("davinci-sim study: --record needs the batch engine (path tasks)", file=sys.stderr)
        return 2
    try:
        # The task's conditions unless the command line gives some (pairs, names, entries).
        conditions = None
        if args.conditions is not None or args.fixture:
            conditions = () if args.conditions is None else parse_conditions(args.conditions, task)
            conditions += tuple(parse_fixture(text) for text in args.fixture or ())
        config = StudyConfig(
            conditions=conditions,
            n_subjects=args.subjects,
            n_repetitions=args.repetitions,
            task=args.task,
            seed=args.seed,
            order=args.order,
            workers=args.workers,
            backend=args.backend,
            timeout=args.timeout,
            engine=args.engine,
            transition=args.transition,
            retention=args.retention,
            prior_practice=args.prior_practice,
            design=args.design,
            mechanisms=tuple(m for m in (args.mechanisms or "").split(",") if m.strip()),
            population=args.population,
        )
    except StudyError as e:
        print(f"davinci-sim study: {e}", file=sys.stderr)
        return 2
    from davinci_sim.study.store import StudyRows

    try:  # where the rows go, before any trial: a new study, or the one to resume
        store = StudyRows.resume(out, config) if args.resume else StudyRows.create(out, config)
    except (StudyError, OSError) as e:
        print(f"davinci-sim study: {e}", file=sys.stderr)
        return 2
    print(
        f"study: {config.n_trials} trials ({config.n_subjects} subjects x "
        f"{len(config.conditions)} conditions x {config.n_repetitions} repetitions"
        + (f" + {config.retention} retention" if config.retention else "")
        + (f", {config.design}-subject" if config.design != "within" else "")
        + (f", mechanisms {'+'.join(config.mechanisms)}" if config.mechanisms else "")
        + "), "
        f"task {config.task}, {config.engine} engine, backend {config.backend}, "
        f"{config.workers} worker(s)",
        flush=True,
    )
    from davinci_sim.study.report import law_summary

    print(law_summary(config.conditions), flush=True)
    for note in store.notes:
        print(f"note: {note}", flush=True)
    if args.resume:
        print(f"resuming: {len(store.rows)} trials kept, "
              f"{config.n_trials - len(store.rows)} to run", flush=True)  # fmt: skip
    return _run_study(args, config, store)


class _Stopped(Exception):
    """SIGTERM while a study runs (handled as Ctrl-C is: the rows kept so far stay)."""


def _run_study(args: argparse.Namespace, config, store) -> int:
    """Run the trials ``store`` does not hold yet, keeping each row as it ends; then write
    the outputs. Stopped (Ctrl-C, SIGTERM), it says how to resume."""
    import signal

    from davinci_sim.study import plan_trials, run_study, write_outputs
    from davinci_sim.study.estimate import estimate_study

    def stop(signum, frame):
        raise _Stopped

    try:
        previous = signal.signal(signal.SIGTERM, stop)
    except ValueError:  # not the main thread: no handler
        previous = None
    try:
        todo = [s for i, s in enumerate(plan_trials(config)) if i not in store.rows]
        if todo and config.kind == "path":  # (calibrated on a path trial's set-up)
            print(estimate_study(config, todo).line(), flush=True)
        result = run_study(config, progress=not args.no_progress, done=dict(store.rows),
                           on_row=store.append, record=args.record)  # fmt: skip
    except (KeyboardInterrupt, _Stopped):
        store.close()
        print(f"davinci-sim study: stopped; {len(store.rows)} of {config.n_trials} trials are "
              f"kept in {store.path}: the same command with --resume runs the rest",
              file=sys.stderr)  # fmt: skip
        return 130
    except (ImportError, RuntimeError) as e:
        _drop_if_empty(store)
        kept = (f" ({len(store.rows)} of {config.n_trials} trials are kept in {store.path}: "
                "--resume runs the rest)" if store.rows else "")  # fmt: skip
        print(f"davinci-sim study: {e}{kept}", file=sys.stderr)
        return 2
    except BaseException:
        _drop_if_empty(store)
        raise
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
    for path in write_outputs(result, args.output):
        print(path)
    store.finish()
    sim_time = sum(r["sim_time"] for r in result.rows)
    print(f"wall time {result.wall_time:.1f} s, simulated time {sim_time:.1f} s", flush=True)
    return 0


def _drop_if_empty(store) -> None:
    """A study that failed before its first row leaves no rows file (nothing to resume)."""
    store.close()
    if not store.rows:
        store.finish()


_RECORD_HELP = (
    "record the session to an MCAP file (Foxglove opens it; `davinci-sim replay` plays it): "
    "joint states, poses, wrenches, events, the task's phases and metrics, every command "
    "with its tick"
)


def cmd_replay(args: argparse.Namespace) -> int:
    """Play a recording back: into the web console and the ROS topics, or check it, or
    convert recordings to a dataset."""
    from davinci_sim.records.mcap_file import McapReadError
    from davinci_sim.records.replay import ReplayError, load_recording

    if args.to_dataset is not None:
        from davinci_sim.records.dataset import to_dataset

        try:
            summary = to_dataset(args.files, args.to_dataset)
        except (McapReadError, ReplayError, OSError, ValueError) as e:
            print(f"davinci-sim replay: {e}", file=sys.stderr)
            return 2
        print(summary.line(), flush=True)
        return 0
    if len(args.files) != 1:
        print(
            "davinci-sim replay: replay one file at a time (several only with --to-dataset)",
            file=sys.stderr,
        )
        return 2
    try:
        recording = load_recording(args.files[0])
    except (McapReadError, ReplayError, OSError) as e:
        print(f"davinci-sim replay: {e}", file=sys.stderr)
        return 2
    if not recording.complete:
        print(
            f"note: {recording.path} was cut off ({recording.contents.problem}); replaying "
            "what it holds",
            flush=True,
        )
    for why in recording.unreplayable:
        print(f"note: a call could not be recorded, the replay of inputs is not exact: {why}")
    if args.check:
        from davinci_sim.records.replay import replay_inputs, replay_states

        try:
            if args.mode == "inputs":
                check = replay_inputs(recording)
            else:
                check = replay_states(recording, speed=args.speed)
        except (ReplayError, ValueError) as e:
            print(f"davinci-sim replay: {e}", file=sys.stderr)
            return 2
        print(
            f"replay of {args.mode}: {check.ticks} recorded ticks compared, largest joint "
            f"difference {check.max_abs_diff:.3g} ({'bit-equal' if check.bit_equal else 'differs'}"
            f"{'' if check.first_diff_tick is None else f' from tick {check.first_diff_tick}'})",
            flush=True,
        )
        return 0 if check.bit_equal else 1
    return _serve_replay(args, recording)


def _serve_replay(args: argparse.Namespace, recording) -> int:
    import signal
    import threading

    from davinci_sim.bridge.app import ServeOptions, serve
    from davinci_sim.bridge.rosbridge.config import BridgeConfig
    from davinci_sim.records.replay import ReplayError, replay_system

    web = not args.no_web
    render_hz = 30.0 if web else None
    try:
        system = replay_system(
            recording, args.mode, speed=args.speed, loop=args.loop, render_hz=render_hz
        )
    except (ReplayError, ValueError) as e:
        print(f"davinci-sim replay: {e}", file=sys.stderr)
        return 2
    d = system.description
    options = ServeOptions(
        scene=d.scene,
        keyframe=d.keyframe,
        seed=d.seed,
        server=not args.no_server,
        bridge=BridgeConfig(host="127.0.0.1", port=args.port),
        images="none" if args.no_images else "jpeg",
        runner="thread",
        render_hz=render_hz,
        duration=args.duration,
    )
    parts = []
    if web:
        from davinci_sim.web.app import web_part
        from davinci_sim.web.server import WebOptions

        parts.append(web_part(WebOptions(host="127.0.0.1", port=args.web_port), bedside=False))
    stop = threading.Event()
    signal.signal(signal.SIGINT, lambda *_: stop.set())
    signal.signal(signal.SIGTERM, lambda *_: stop.set())

    def ready(info: dict) -> None:
        if "url" in info:
            print(f"rosbridge server: {info['url']}", flush=True)
        if "web" in info:
            print(f"web console: {info['web']}  <- open this in a browser", flush=True)
        print(
            f"replaying {recording.path} ({args.mode}, {args.speed:g}x; Ctrl-C to stop)", flush=True
        )

    try:
        info = serve(options, stop=stop, on_ready=ready, parts=parts, system=system,
                     freeze_heap=True)  # fmt: skip
    except OSError as e:
        print(f"davinci-sim replay: {e}; choose another port (--port, --web-port)", file=sys.stderr)
        return 2
    print(f"stopped; replayed at {info.get('sim_over_wall', 0):.3f}x real time", flush=True)
    return 0


def _replay_parser(sub) -> None:
    p = sub.add_parser("replay", help="play a recording (serve --record) back, or make a dataset")
    p.add_argument("files", nargs="+", metavar="FILE.mcap")
    p.add_argument(
        "--mode",
        default="inputs",
        choices=["inputs", "states"],
        help="inputs: the recorded commands re-run through the physics; states: the "
        "recorded joint positions shown as they were (default: inputs)",
    )
    p.add_argument(
        "--speed",
        type=float,
        default=1.0,
        help="times real time (inputs: 0 runs as fast as it computes)",
    )
    p.add_argument("--loop", action="store_true", help="states: start again at the end")
    p.add_argument(
        "--check",
        action="store_true",
        help="no viewer: replay as fast as possible and compare with the recorded "
        "joint positions (exit 1 if they differ)",
    )
    p.add_argument(
        "--to-dataset",
        default=None,
        metavar="OUT.hdf5",
        help="convert the recordings to an imitation-learning dataset (robomimic's "
        "HDF5 layout) instead",
    )
    p.add_argument("--port", type=int, default=9090, help="rosbridge server port")
    p.add_argument("--no-server", action="store_true", help="no rosbridge server")
    p.add_argument("--no-images", action="store_true", help="no image topics")
    p.add_argument("--web-port", type=int, default=8080)
    p.add_argument("--no-web", action="store_true", help="no web console")
    p.add_argument("--duration", type=float, default=None, help="stop after this many seconds")
    p.set_defaults(func=cmd_replay)


_RECORDS_HELP = (
    "the trainee records file (default: $DAVINCI_SIM_RECORDS, else "
    "$XDG_DATA_HOME/davinci-sim/records.sqlite3, else ~/.local/share/davinci-sim/records.sqlite3)"
)


def cmd_run(args: argparse.Namespace) -> int:
    from davinci_sim.compat.run import RunOptions, run_script

    options = RunOptions(
        connect=args.connect, scene=args.scene, keyframe=args.keyframe, seed=args.seed,
        console=not args.no_console, home=args.home, rate=args.rate, token=args.token,
        force_compat=args.force_compat, freeze_heap=True, sim_time=args.sim_time,
    )  # fmt: skip
    try:
        return run_script(args.script, args.args, options)
    except (FileNotFoundError, ConnectionError, ValueError) as e:
        print(f"davinci-sim run: {e}", file=sys.stderr)
        return 2


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    return args.func(args)


def build_parser() -> argparse.ArgumentParser:
    """The ``davinci-sim`` command's parser (each sub-command's ``func`` in its defaults)."""
    parser = argparse.ArgumentParser(
        prog="davinci-sim", description="Simulator of the da Vinci Research Kit (dVRK)."
    )
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("info", help="arms, joints and scene variants")
    p.set_defaults(func=cmd_info)
    p = sub.add_parser("urdf", help="the robot's URDF (generated from the model), to stdout")
    p.add_argument("--scene", default="full", choices=_scene_names())
    p.add_argument("--arm", default=None, help="one arm alone (PSM1, SUJ/PSM1 …), as the dVRK's")
    p.add_argument("--output", "-o", default=None, help="write to this file instead")
    p.set_defaults(func=cmd_urdf)
    p = sub.add_parser("snapshot", help="endoscope images and an overview as PNG")
    p.add_argument("--scene", default="full", choices=_scene_names())
    p.add_argument("--output", "-o", default="snapshots", help="folder for the PNG files")
    p.add_argument("--no-home", action="store_true", help="do not home the arms first")
    p.add_argument(
        "--keyframe",
        default="surgical",
        choices=["surgical", "home"],
        help="initial pose: 'surgical' (ECM setup joints posed so the endoscope sees the "
        "instruments, default) or 'home' (the dVRK's simulated setup-joint positions)",
    )
    p.add_argument("--task", default=None, help="draw a task's path (name or file), e.g. seed_path")
    p.set_defaults(func=cmd_snapshot)
    p = sub.add_parser("demo", help="headless scripted demo of every arm")
    p.add_argument("--scene", default="full", choices=_scene_names())
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--keyframe", default="home", choices=["home", "surgical"])
    p.set_defaults(func=cmd_demo)
    p = sub.add_parser(
        "serve",
        help="run the simulation with its ROS interfaces (rosbridge v2 server, UDP, client mode)",
    )
    p.add_argument("--scene", default="full", choices=_scene_names())
    p.add_argument("--keyframe", default="surgical", choices=["surgical", "home"])
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--fast", action="store_true", help="as fast as possible, not real time")
    p.add_argument(
        "--stepped",
        action="store_true",
        help="the simulation ticks only the time a page asks for (the web console's advance "
        "op; window.davinci.advance(seconds) in the page): for scripts that drive the page "
        "and look at each state before they act",
    )
    p.add_argument("--home", action="store_true", help="enable and home every arm at start")
    p.add_argument(
        "--host", default="127.0.0.1", help="interface to bind (default loopback; 0.0.0.0 for all)"
    )
    p.add_argument("--port", type=int, default=9090)
    p.add_argument(
        "--ros-version",
        type=int,
        choices=[1, 2],
        default=2,
        help="dialect: 1 (pkg/Type, secs/nsecs, Header seq) or 2 (default)",
    )
    p.add_argument(
        "--rate",
        type=float,
        default=100.0,
        help="publish rate of the arms' state topics, Hz (dVRK default 100, max 1000)",
    )
    p.add_argument("--tf-rate", type=float, default=50.0)
    p.add_argument(
        "--images",
        default="jpeg",
        choices=["jpeg", "raw", "both", "none"],
        help="endoscope topics: CompressedImage JPEG (default), raw Image, both, none",
    )
    p.add_argument("--image-rate", type=float, default=30.0)
    p.add_argument("--rig", default="jhu_daVinci", help="namespace of the stereo image topics")
    p.add_argument(
        "--max-message-size", type=int, default=10_000_000, help="largest incoming message, bytes"
    )
    p.add_argument(
        "--token",
        default=None,
        help="require rosbridge 'auth' with this token (or $DAVINCI_SIM_TOKEN)",
    )
    p.add_argument(
        "--stamps",
        default="wall",
        choices=["wall", "sim"],
        help="header stamps: wall clock (ROS time, default) or simulation time",
    )
    p.add_argument("--no-server", action="store_true", help="no rosbridge server")
    p.add_argument(
        "--udp",
        action="store_true",
        help="dVRK socket-streamer UDP JSON streams (PSM1 48051, PSM2 48052, ECM "
        "48053, MTML 48054, MTMR 48055, PSM3 48056)",
    )
    p.add_argument("--udp-ports", default="", help="override ports, e.g. PSM1=49051,ECM=49053")
    p.add_argument("--udp-ip", default="127.0.0.1", help="destination of the UDP streams")
    p.add_argument(
        "--ros-connect",
        default=None,
        metavar="ws://HOST:9090",
        help="client mode: connect to an existing rosbridge_server (the simulated arms "
        "publish their state there and take the commands published there)",
    )
    p.add_argument(
        "--namespace",
        default="/sim",
        help="client mode: prefix of the simulated arms' topics on the remote ('/': none, "
        "the simulated arms answer to the dVRK's own topic names)",
    )
    p.add_argument("--remote-ros-version", type=int, choices=[1, 2], default=2)
    p.add_argument(
        "--joint-errors",
        action="append",
        default=[],
        metavar="PSMn=YAW,PITCH,INSERTION",
        help="robot inaccuracy: the PSM's links stand at its joints plus these errors (rad, "
        "rad, m) while it reports and servoes its joints by the nominal kinematics, as the "
        "AccelNet challenge perturbs its PSMs; repeat per PSM",
    )
    p.add_argument(
        "--random-joint-errors",
        type=int,
        default=None,
        metavar="SEED",
        help="robot inaccuracy drawn for every PSM of the scene from SEED, uniform within "
        "±5 deg, ±5 deg, ±5 mm (the challenge's range)",
    )
    p.add_argument(
        "--no-robot-description",
        action="store_true",
        help="client mode: do not publish the robot on the remote (by default NS/"
        "robot_description latched, /tf_static, and /tf and NS/joint_states at --tf-rate, "
        "frames prefixed 'NS/', for RViz: about 0.5 MB/s to the remote for PSM1+ECM at "
        "50 Hz, 1.3 MB/s for the full system; a lower --tf-rate costs proportionally less)",
    )
    p.add_argument(
        "--console",
        action="store_true",
        help="the surgeon console and teleoperations (MTMs fed by the client mode with "
        "--ros-connect), and the web console's keyboard hands on the simulated MTMs; without "
        "it the console, its teleoperations and the /console/* and /footpedals/* topics are "
        "still there when the scene has an MTM and a PSM",
    )
    p.add_argument(
        "--no-console",
        action="store_true",
        help="no surgeon console: no teleoperations, no /console/* or /footpedals/* topics",
    )
    p.add_argument(
        "--task",
        default=None,
        help="a training task to do at the console (name, e.g. seed_path, or file): its path "
        "is drawn, its fixture guides, its repetitions are measured (/task/* topics); "
        "implies --console",
    )
    p.add_argument(
        "--condition",
        default=None,
        help="the task's condition: a condition name (e.g. 'B=40'), B:G_max, e.g. 40:5, or a "
        "fixture entry (YAML mapping), e.g. '{type: adaptive, mode: fading, B0: 40, zero_at: 8}' "
        "(default: the task's own fixture)",
    )
    p.add_argument("--task-log", default=None, help="CSV file the repetitions are appended to")
    p.add_argument(
        "--trainee",
        default=None,
        help=f"whose attempts these are: each finished repetition of --task is recorded in "
        f"the trainee records under this name (default: {DEFAULT_TRAINEE!r})",
    )
    p.add_argument("--records", default=None, metavar="FILE", help=_RECORDS_HELP)
    p.add_argument("--no-records", action="store_true", help="do not record the attempts")
    p.add_argument(
        "--runner",
        default=None,
        choices=["thread", "process"],
        help="the loop in a thread of this process, or in its own process (default: its own "
        "process with the web console, else a thread)",
    )
    p.add_argument("--duration", type=float, default=None, help="stop after this many seconds")
    p.add_argument(
        "--web-port", type=int, default=8080, help="port of the web console (default 8080)"
    )
    p.add_argument("--no-web", action="store_true", help="no web console")
    p.add_argument(
        "--realtime-priority",
        type=int,
        default=None,
        metavar="N",
        help="run the loop process with SCHED_FIFO priority N (1-99) as the dVRK runs its "
        "control loops; needs root or CAP_SYS_NICE, else it runs at normal priority",
    )
    p.add_argument("--no-bedside", action="store_true", help="web console without the 3-D view")
    p.add_argument("--record", default=None, metavar="FILE.mcap", help=_RECORD_HELP)
    p.add_argument(
        "--record-images",
        type=float,
        default=None,
        metavar="HZ",
        help="with --record: the stereo endoscope's images too, as JPEG, at HZ",
    )
    p.add_argument(
        "--record-rate",
        type=float,
        default=None,
        metavar="HZ",
        help="with --record: the states at HZ at most (default: every published state, --rate)",
    )
    p.add_argument("-v", "--verbose", action="store_true")
    p.set_defaults(func=cmd_serve)
    _replay_parser(sub)
    _class_parser(sub)
    p = sub.add_parser("task", help="check a training task (reachability, view)")
    task_sub = p.add_subparsers(dest="task_command", required=True)
    p = task_sub.add_parser(
        "check", help="is each point reachable by the task's PSM and in the endoscope's view?"
    )
    p.add_argument("file", help="task name (e.g. seed_path) or task file")
    p.set_defaults(func=cmd_task_check)
    p = sub.add_parser("trainees", help="the trainee records: list, show, export, curves")
    trainees_sub = p.add_subparsers(dest="trainees_command", required=True)
    p = trainees_sub.add_parser("list", help="the trainees, their sessions and attempts")
    p.add_argument("--records", default=None, metavar="FILE", help=_RECORDS_HELP)
    p.set_defaults(func=cmd_trainees)
    p = trainees_sub.add_parser("show", help="a trainee's sessions, attempts, latest metrics")
    p.add_argument("name", help="the trainee")
    p.add_argument("--records", default=None, metavar="FILE", help=_RECORDS_HELP)
    p.set_defaults(func=cmd_trainees)
    p = trainees_sub.add_parser("export", help="every attempt as CSV, the metrics as columns")
    p.add_argument("--csv", nargs="?", const="-", default="-", metavar="FILE",
                   help="CSV file (default: standard output)")  # fmt: skip
    p.add_argument("--trainee", default=None, help="only this trainee's attempts")
    p.add_argument("--records", default=None, metavar="FILE", help=_RECORDS_HELP)
    p.set_defaults(func=cmd_trainees)
    p = trainees_sub.add_parser("curve", help="a trainee's learning curves as a PNG figure")
    p.add_argument("name", help="the trainee")
    p.add_argument("--task", default=None, help="one task (default: each task, one row each)")
    p.add_argument("--metric", action="append", default=None,
                   help="a metric to draw (repeatable; 'score': the overall score; default: "
                   "the score if scored, then each metric with a better direction)")  # fmt: skip
    p.add_argument("--pass-mark", action="append", default=None, metavar="METRIC=VALUE",
                   help="pass mark of a metric, in its unit (repeatable): the pass band is "
                   "drawn (the score's recorded pass mark is used by default)")  # fmt: skip
    p.add_argument("--output", "-o", required=True, help="the PNG file")
    p.add_argument("--records", default=None, metavar="FILE", help=_RECORDS_HELP)
    p.set_defaults(func=cmd_trainees)
    p = sub.add_parser(
        "study", help="the seed's user study with synthetic trainees (CSV, figures, report)"
    )
    p.add_argument("--subjects", type=int, default=10)
    p.add_argument("--repetitions", type=int, default=10, help="repetitions per condition")
    p.add_argument(
        "--conditions",
        default=None,
        help="B:G_max pairs (N·s/m:N, the seed's viscous law) or the task's condition names, "
        "e.g. '0:0,20:2,40:5,60:8' (default: the task's conditions, else the seed's Table I)",
    )
    p.add_argument(
        "--fixture",
        action="append",
        metavar="ENTRY",
        help="a condition as a fixture entry (YAML mapping), e.g. "
        "'{type: spring, stiffness: 200, name: k200}' or '{type: mypkg.laws:MyLaw, k: 1}'; "
        "repeat for more (after the --conditions ones)",
    )
    p.add_argument(
        "--transition",
        type=float,
        default=None,
        metavar="M",
        help="on-path ramp of the viscous conditions that set none, m (default 0: the seed's "
        "law as printed; e.g. 0.0005 for a 0.5 mm ramp)",
    )
    p.add_argument(
        "--retention",
        type=int,
        default=0,
        metavar="N",
        help="N repetitions with the fixture off after each condition's practice block "
        "(rows with block=retention; the report compares the conditions on them)",
    )
    p.add_argument(
        "--prior-practice",
        type=int,
        default=0,
        metavar="N",
        help="trials of practice each subject had before the study (their practice count "
        "starts at N: subjects who trained first, as Enayati et al.'s did for 23 min)",
    )
    p.add_argument(
        "--population",
        default="trainee",
        help="the synthetic trainees: trainee (the parameter table's novices), expert, or a "
        "fitted profile (rota2023: fitted to Rota's dVRK-console control group)",
    )
    p.add_argument(
        "--design",
        default="within",
        choices=["within", "between", "rota"],
        help="within: every subject does every condition (counterbalanced); between: "
        "subject s does condition s mod C only; rota: Rota's protocol, a control group "
        "(the first condition) and an assisted group (the others, one a day), --repetitions "
        "trials a day",
    )
    p.add_argument(
        "--mechanisms",
        default=None,
        metavar="NAMES",
        help="trainee reactions to guidance, comma-separated: reliance (guided practice "
        "trains the own correction less), stiffening (co-contraction under strong force); "
        "default: none",
    )
    p.add_argument("--task", default="seed_path", help="task name or task file")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--order",
        default="latin",
        choices=["latin", "fixed"],
        help="condition order: counterbalanced Williams Latin square per subject, or as listed",
    )
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--backend", default="local", choices=["local", "ray"])
    p.add_argument(
        "--engine",
        default=None,
        choices=["batch", "live"],
        help="batch: trials stepped together (fast); live: one full simulation per trial "
        "(the slow reference); default batch for a path task, live for a needle exercise "
        "(its only engine)",
    )
    p.add_argument(
        "--timeout",
        type=float,
        default=60.0,
        help="simulated seconds before a trial is unfinished (path tasks; a needle exercise "
        "ends at its own time limit)",
    )
    p.add_argument("--output", "-o", default="study", help="output folder")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument(
        "--record",
        default=None,
        metavar="DIR",
        help="record every trial to DIR, one MCAP file per trial (batch engine): the PSM "
        "and MTM at 100 Hz, the guidance force, the phase, the row",
    )
    p.add_argument(
        "--resume",
        action="store_true",
        help="finish the interrupted study in the output folder (same options): run only "
        "the trials whose rows it did not keep",
    )
    p.set_defaults(func=cmd_study)
    p = sub.add_parser(
        "run",
        help="run an unmodified dVRK Python script (crtk, dvrk, PyKDL) against the simulator",
        description="Runs SCRIPT with its ARGS as __main__, with the crtk and dvrk packages "
        "(crtk_python / dvrk_python API) and a PyKDL subset on its import path, against a "
        "simulation started in this process (default) or a running rosbridge server "
        "(--connect). An installed ROS crtk/dvrk/PyKDL is not shadowed.",
    )
    p.add_argument(
        "--connect",
        default=None,
        metavar="ws://HOST:PORT",
        help="use a running rosbridge server (davinci-sim serve, or a real one)",
    )
    p.add_argument("--token", default=None, help="--connect: the server's token")
    p.add_argument("--scene", default="full", choices=_scene_names())
    p.add_argument("--keyframe", default="home", choices=["home", "surgical"])
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--no-console",
        action="store_true",
        help="in-process: no surgeon console (teleoperations, pedals)",
    )
    p.add_argument("--home", action="store_true", help="in-process: enable and home the arms")
    p.add_argument(
        "--rate",
        type=float,
        default=100.0,
        help="in-process: publish rate of the arms' states, Hz (default 100)",
    )
    p.add_argument(
        "--force-compat",
        action="store_true",
        help="use davinci-sim's crtk and dvrk even if ROS's are installed",
    )
    p.add_argument(
        "--sim-time",
        action="store_true",
        help="the script's rates and ral.now() follow the simulation's /clock (ROS's "
        "use_sim_time), not the wall clock: its loops keep their rate in simulated time "
        "when the simulation runs below real time",
    )
    p.add_argument("script", help="the Python script")
    p.add_argument("args", nargs=argparse.REMAINDER, help="the script's arguments")
    p.set_defaults(func=cmd_run)
    return parser


if __name__ == "__main__":
    sys.exit(main())
