"""A run directory's files: ``results.csv`` (append-only, fsynced row by row) and ``run.json``.

A re-run reads back what is recorded and skips it; a row cut short by a kill
is dropped; a directory made with another configuration is refused.
"""

from __future__ import annotations

import csv
import json
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from dualpilot.evaluation.missions import COLUMNS


def read_results(path: Path) -> list[dict[str, str]]:
    if not path.exists():
        return []
    with path.open(newline="") as fh:
        return list(csv.DictReader(fh))


class ResultsFile:
    """Append-only CSV; each row is flushed and fsynced as soon as it is written.

    A row cut short by a kill (no final newline) is dropped when the file is reopened.
    """

    def __init__(self, path: Path, columns: Sequence[str] = COLUMNS):
        self.path = path
        _drop_partial_line(path)
        new = not path.exists() or path.stat().st_size == 0
        if not new:
            with path.open(newline="") as fh:
                header = next(csv.reader(fh), [])
            if header != list(columns):
                raise ValueError(f"{path} has other columns; use another --out")
        self.fh = path.open("a", newline="")
        self.writer = csv.DictWriter(self.fh, fieldnames=list(columns), extrasaction="ignore")
        if new:
            self.writer.writeheader()
            self._sync()

    def _sync(self) -> None:
        self.fh.flush()
        os.fsync(self.fh.fileno())

    def append(self, row: Mapping[str, object]) -> None:
        self.writer.writerow(row)
        self._sync()

    def close(self) -> None:
        self.fh.close()


def _drop_partial_line(path: Path) -> None:
    if not path.exists() or path.stat().st_size == 0:
        return
    data = path.read_bytes()
    if not data.endswith(b"\n"):
        with path.open("r+b") as fh:
            fh.truncate(data.rfind(b"\n") + 1)


def write_parquet(csv_path: Path, out: Path) -> Path:
    """The CSV table as Parquet (types inferred by pyarrow)."""
    import pyarrow.csv as pacsv
    import pyarrow.parquet as pq

    pq.write_table(pacsv.read_csv(csv_path), out)
    return out


def check_config(out: Path, config: Mapping[str, Any]) -> None:
    """Refuse to resume a run directory made with another configuration."""
    path = out / "run.json"
    if path.exists():
        old = json.loads(path.read_text())
        diff = {k for k in set(old) | set(config) if old.get(k) != config.get(k)}
        if diff:
            raise ValueError(f"{out} holds a run with other {', '.join(sorted(diff))} "
                             f"({', '.join(f'{k}={old.get(k)!r}' for k in sorted(diff))}); "
                             "use another --out")
    path.write_text(json.dumps(config, indent=2) + "\n")
