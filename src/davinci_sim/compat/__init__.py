"""dVRK users' own Python code against the simulator: crtk_python's ``crtk``, dvrk_python's
``dvrk`` and a PyKDL subset, with the originals' classes, methods, return values, waits,
time-outs and exceptions.

* :mod:`~davinci_sim.compat.kdl` — ``PyKDL``'s ``Vector``, ``Rotation``, ``Frame``,
  ``Twist``, ``Wrench``, ``JntArray`` (used only when the real PyKDL is missing);
* :mod:`~davinci_sim.compat.ral` — ``crtk.ral``; :mod:`~davinci_sim.compat.crtk_utils` —
  ``crtk.utils`` and its ``add_*`` helpers, ``wait_move_handle``, ``joystick_button``;
* :mod:`~davinci_sim.compat.dvrk_api` — ``dvrk.arm``, ``psm``, ``ecm``, ``mtm``, ``suj``,
  ``console``, ``system``, ``teleop_psm``;
* :mod:`~davinci_sim.compat.transport` — the rosbridge client every ``ral`` talks through,
  over a websocket or, :mod:`~davinci_sim.compat.inprocess`, to the bridge in this process
  without a socket;
* :mod:`~davinci_sim.compat.run` — ``davinci-sim run script.py``; ``shim/`` holds the
  importable ``crtk``, ``dvrk`` and ``PyKDL`` it puts on the script's path.

Layer: beside ``web`` (11); it uses ``system`` (the in-process simulation) and ``bridge``
(the rosbridge core and the dVRK nodes).
"""
