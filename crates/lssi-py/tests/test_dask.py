"""A fleet on a Dask LocalCluster: each result equals the single-machine one."""
import pytest

import lssi
import lssi.dask
from conftest import duffing

distributed = pytest.importorskip("dask.distributed")


def test_identify_many_on_a_local_cluster():
    recordings = []
    for seed in range(20):
        t, x = duffing(n=6000, dt=0.005, seed=seed, noise=0.005)
        recordings.append({"t": t, "x": x})
    options = dict(omega=1.2)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        table = lssi.dask.identify_many(recordings, client=client, **options)
    assert len(table) == 20
    assert table["error"].isna().all(), table["error"].tolist()
    for row, rec in zip(table.itertuples(), recordings):
        local = lssi.Model(**options).fit(rec["x"], t=rec["t"])
        assert row.report == local.report()
        assert row.equation == local.equation()


def test_a_failing_recording_gets_its_error_in_its_row(tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("t,x\n0,1\n")
    row = lssi.dask.identify_one(bad)
    assert row["error"] and "bad.csv" in row["error"]
    assert row["equation"] is None
