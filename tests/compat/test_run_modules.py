"""``davinci-sim run`` without a simulation: which crtk/dvrk/PyKDL it picks, how it puts
them on the import path, the script's exit codes, and its errors."""

from __future__ import annotations

import importlib
import os
import sys

import pytest

from davinci_sim import cli
from davinci_sim.compat import pykdl
from davinci_sim.compat import run as run_module
from davinci_sim.compat.run import KDL_SHIM, MSG_SHIM, ROS_SHIM, install_modules, module_choice


@pytest.fixture
def clean_path(monkeypatch):
    """Restore ``sys.path``, ``sys.modules`` entries and ``PYTHONPATH`` after the test."""
    monkeypatch.setattr(sys, "path", list(sys.path))
    monkeypatch.setenv("PYTHONPATH", os.environ.get("PYTHONPATH", ""))
    monkeypatch.setenv(pykdl.ENV, "subset")  # as a machine without a system PyKDL
    saved = {n: sys.modules.get(n) for n in ("crtk", "dvrk", "PyKDL")}
    yield monkeypatch
    for name, module in saved.items():
        if module is None:
            sys.modules.pop(name, None)
        else:
            sys.modules[name] = module
    importlib.invalidate_caches()


def workspace(folder, *names):
    for name in names:
        if name == "PyKDL":
            (folder / "PyKDL.py").write_text("")
        else:
            (folder / name).mkdir()
            (folder / name / "__init__.py").write_text("")
    return folder


def test_choice_follows_what_is_installed(clean_path, tmp_path):
    for n in ("crtk", "dvrk", "PyKDL"):
        sys.modules.pop(n, None)
    choice = module_choice()
    assert choice.ours_for_ros and choice.real_kdl is None
    ws = workspace(tmp_path, "crtk", "dvrk", "PyKDL")
    sys.path.insert(0, str(ws))
    importlib.invalidate_caches()
    choice = module_choice()
    assert not choice.ours_for_ros
    assert choice.real_crtk.startswith(str(ws)) and choice.real_kdl.startswith(str(ws))
    assert "the installed ones" in choice.describe()
    assert module_choice(force_compat=True).ours_for_ros


def test_half_a_ros_installation_gets_ours_for_both(clean_path, tmp_path):
    sys.path.insert(0, str(workspace(tmp_path, "crtk")))  # crtk without dvrk
    importlib.invalidate_caches()
    choice = module_choice()
    assert choice.real_crtk and not choice.real_dvrk and choice.ours_for_ros
    install_modules(choice)
    assert sys.path[0] == str(ROS_SHIM) and sys.path[-2:] == [str(KDL_SHIM), str(MSG_SHIM)]
    import crtk
    import dvrk

    assert crtk.__file__.startswith(str(ROS_SHIM)) and dvrk.__file__.startswith(str(ROS_SHIM))
    assert callable(crtk.ral) and callable(dvrk.psm)


def test_ours_are_not_found_as_real(clean_path):
    install_modules(module_choice())
    importlib.invalidate_caches()
    choice = module_choice()  # our shims on the path are not "installed ones"
    assert choice.ours_for_ros and choice.real_kdl is None
    import PyKDL

    assert PyKDL.Frame is importlib.import_module("davinci_sim.compat.kdl").Frame


def test_a_system_pykdl_is_used_when_the_interpreter_can_load_it(clean_path):
    clean_path.delenv(pykdl.ENV)
    found = pykdl.find()
    if found is None:
        pytest.skip("no system PyKDL for this interpreter (Debian: apt-get install python3-pykdl)")
    assert found.name.endswith(pykdl.suffix())
    sys.modules.pop("PyKDL", None)
    choice = module_choice()
    assert choice.real_kdl == str(found) and f"PyKDL: the system's ({found})" in choice.describe()
    install_modules(choice)
    importlib.invalidate_caches()
    import PyKDL

    assert PyKDL is pykdl.load(found) and PyKDL.__file__ == str(found)
    goal, start = PyKDL.Frame(), PyKDL.Frame(PyKDL.Vector(1.0, 2.0, 3.0))
    goal.p = start.p
    goal.p[0] = 9.0
    assert start.p[0] == 1.0  # the real one copies on assignment


def test_exit_codes_as_python(tmp_path):
    ok = tmp_path / "ok.py"
    ok.write_text("import sys\nassert sys.argv[1:] == ['-a', 'PSM1']\n")
    assert run_module.run_path_as_main(str(ok), ["-a", "PSM1"]) == 0
    code = tmp_path / "code.py"
    code.write_text("import sys\nsys.exit(3)\n")
    assert run_module.run_path_as_main(str(code), []) == 3
    text = tmp_path / "text.py"
    text.write_text("import sys\nsys.exit('failed to home within 10 seconds')\n")
    assert run_module.run_path_as_main(str(text), []) == 1
    raises = tmp_path / "raises.py"
    raises.write_text("raise ValueError('the script is wrong')\n")
    assert run_module.run_path_as_main(str(raises), []) == 1  # not taken for our own error


def test_cli_errors(clean_path, tmp_path, capsys):
    assert cli.main(["run", str(tmp_path / "missing.py")]) == 2  # said before any start
    assert "no such script" in capsys.readouterr().err
    script = tmp_path / "x.py"
    script.write_text("print('never')\n")
    before = os.environ.get("PYTHONPATH")
    assert cli.main(["run", "--connect", "ws://127.0.0.1:9", str(script)]) == 2
    captured = capsys.readouterr()
    assert "cannot connect" in captured.err and "never" not in captured.out
    assert os.environ.get("PYTHONPATH") == before  # (the script's environment put back)
