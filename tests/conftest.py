"""Settings of every test."""

import os

import pytest


@pytest.fixture(autouse=True, scope="session")
def _records_in_a_temporary_folder(tmp_path_factory):
    """``serve --task`` records every attempt in the trainee records: in the tests, a file of
    a temporary folder, never the user's own records (``$DAVINCI_SIM_RECORDS``, set for the
    whole session so that module fixtures and the processes tests start have it too)."""
    before = os.environ.get("DAVINCI_SIM_RECORDS")
    folder = tmp_path_factory.mktemp("records")
    os.environ["DAVINCI_SIM_RECORDS"] = str(folder / "records.sqlite3")
    yield
    if before is None:
        os.environ.pop("DAVINCI_SIM_RECORDS", None)
    else:
        os.environ["DAVINCI_SIM_RECORDS"] = before
