"""Identify a fleet of recordings on a Dask cluster.

    from dask.distributed import Client, LocalCluster
    import lssi.dask
    with Client(LocalCluster(n_workers=2)) as client:
        table = lssi.dask.identify_many(["a.csv", "b.csv"], client=client, harmonics=1)

One task per recording, each running the same identification as ``lssi.identify`` (a file
path) or ``Model.fit`` (a dict of arrays ``{"t": ..., "x": ..., "v": ..., "u": ...}``, with
``"V"`` or ``"i"`` for a harvester's system, or a pandas DataFrame): refined on simulation error by default, as ``lssi identify`` refines one
recording (``refine=False``: the streaming model, as its batches report). It runs unchanged
on a ``LocalCluster`` or a real scheduler's ``Client``.
"""

from __future__ import annotations

import json
import os
from typing import Any, Dict, Iterable, Optional

import pandas as pd

__all__ = ["identify_one", "identify_many"]


def identify_one(item: Any, name: Optional[str] = None, **options) -> Dict[str, Any]:
    """Identifies one recording (a path, a dict of arrays or a DataFrame); a failure is a
    row with its error, never an exception."""
    import lssi

    if name is None:
        name = os.fspath(item) if isinstance(item, (str, os.PathLike)) else "array"
    row: Dict[str, Any] = {"name": name, "error": None, "equation": None, "terms": None,
                           "coefficients": None, "report": None}
    try:
        if isinstance(item, (str, os.PathLike)):
            model = lssi.identify(item, **options)
        else:
            data = item
            if isinstance(item, dict):
                data = {k: item.get(k) for k in ("x", "t", "v", "u", "V", "i")}
                model = lssi.Model(**options).fit(data["x"], t=data["t"], v=data["v"], u=data["u"],
                                                  V=data["V"], i=data["i"])
            else:
                model = lssi.Model(**options).fit(data)
        report = json.loads(model.to_json())
        if model.is_system():
            # A system (an electrical channel V or i): per equation, by target.
            terms = {e["target"]: [term["term"] for term in e["terms"]] for e in report["equations"]}
            coefficients = model.equations()
        else:
            terms = [term["term"] for term in report["terms"]]
            coefficients = {term["term"]: term["coef"] for term in report["terms"]}
        row.update(equation=model.equation(), terms=terms, coefficients=coefficients,
                   report=report)
    except (ValueError, RuntimeError) as e:
        row["error"] = str(e)
    return row


def identify_many(items: Iterable[Any], client=None, names: Optional[Iterable[str]] = None,
                  **options) -> pd.DataFrame:
    """Maps ``identify_one`` over a Dask cluster: one task per recording, results in input
    order as a DataFrame (columns name, error, equation, terms, coefficients, report).
    ``client`` defaults to the current Dask client (``distributed.get_client()``)."""
    from dask.distributed import get_client

    items = list(items)
    names = list(names) if names is not None else [None] * len(items)
    if len(names) != len(items):
        raise ValueError(f"{len(names)} names for {len(items)} recordings.")
    client = client or get_client()
    futures = [
        client.submit(identify_one, item, name, pure=False, **options)
        for item, name in zip(items, names)
    ]
    return pd.DataFrame(client.gather(futures))
