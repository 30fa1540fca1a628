"""Identify a campaign of recordings on a Dask cluster (here a LocalCluster; pass the
address of a real scheduler to Client(...) instead) and print one line per recording.

    bash scripts/setup-python.sh
    .venv/bin/python examples/fleet.py data/*.csv
"""
import sys

from dask.distributed import Client, LocalCluster

import lssi.dask


def main(paths):
    with LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        table = lssi.dask.identify_many(paths, client=client)
    for row in table.itertuples():
        print(f"{row.name}: {row.error or row.equation}")


if __name__ == "__main__":
    main(sys.argv[1:] or ["data/eveh-bistable.csv", "data/eveh-monostable.csv", "data/paper-eq17.csv"])
