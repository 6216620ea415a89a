"""``davinci-sim serve --task … --trainee NAME``: the trainee's session is in the records
from the start, and the ready message says where."""

from __future__ import annotations

from davinci_sim.cli import main
from davinci_sim.records import RecordsDB


def test_serve_with_a_task_records_the_trainees_session(tmp_path, capsys):
    path = tmp_path / "records.sqlite3"
    code = main(["serve", "--scene", "psm1_ecm_mtmr", "--task", "seed_path", "--trainee", "ana",
                 "--records", str(path), "--no-web", "--port", "0", "--images", "none",
                 "--duration", "0.5"])  # fmt: skip
    out = capsys.readouterr().out
    assert code == 0
    assert f"trainee records: {path} (trainee 'ana')" in out
    with RecordsDB(path, create=False) as db:
        (session,) = db.sessions("ana")
    assert session["source"] == "serve" and session["attempts"] == 0
    assert session["ended_at"] is not None and session["started_at"] < session["ended_at"]


def test_serve_records_in_the_per_user_file_unless_told_not_to(tmp_path, capsys, monkeypatch):
    path = tmp_path / "mine.sqlite3"
    monkeypatch.setenv("DAVINCI_SIM_RECORDS", str(path))
    argv = ["serve", "--scene", "psm1_ecm_mtmr", "--task", "seed_path", "--no-web", "--port",
            "0", "--images", "none", "--duration", "0.2"]  # fmt: skip
    assert main([*argv, "--no-records"]) == 0
    assert not path.exists() and "trainee records" not in capsys.readouterr().out
    assert main(argv) == 0
    assert "(trainee 'guest')" in capsys.readouterr().out
    with RecordsDB(path, create=False) as db:
        assert [t["name"] for t in db.trainees()] == ["guest"]
