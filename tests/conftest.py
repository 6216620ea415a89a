"""Settings of every test."""

import pytest


@pytest.fixture(autouse=True)
def _records_in_a_temporary_folder(tmp_path_factory, monkeypatch):
    """``serve --task`` records every attempt in the trainee records: in the tests, a file of
    a temporary folder, never the user's own records (``$DAVINCI_SIM_RECORDS``; tests that
    start processes pass it on)."""
    folder = tmp_path_factory.mktemp("records", numbered=True)
    monkeypatch.setenv("DAVINCI_SIM_RECORDS", str(folder / "records.sqlite3"))
