"""Run logs: written as the run goes, readable after any interruption.

Format (documented in ``docs/log-format.md``): a folder ``log/`` of Parquet files
``part-00000.parquet``, ``part-00001.parquet`` …, each a complete Parquet file holding
consecutive rows. A crash, Ctrl-C or divergence loses at most the rows not yet flushed
(one chunk, ``flush_every`` rows); every part already on disk stays readable.

The columns are a superset of measurement data format v1 (``docs/data-format.md``), so a
run log is itself a valid data set for ``granular-mpc validate``:

* v1 columns: ``time``, ``stance``, ``q_<joint>``, ``dq_<joint>``, ``tau_<joint>``,
  ``base_x..z``, ``base_qw, base_qx, base_qy, base_qz``, ``base_vx..vz`` (world),
  ``base_wx..wz`` (trunk frame), ``grf_x..z`` and ``intrusion_x..z`` of the stance foot;
* per foot (``left_`` / ``right_``): ``grf_x..z``, ``intrusion_x..z``, ``contact`` (0/1),
  ``depth`` (lowest sole point below the surface, m), ``px, py, pz`` (contact point, W),
  ``pitch`` (ψ_c, rad), ``cap_z`` (vertical capacity at the current depth, N);
* whole body: ``com_x..z``, ``com_vx..vz``;
* controller columns added by the caller (``cmd_vx``, ``mpc_solve_ms`` …).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

import numpy as np
import pinocchio as pin

from .exceptions import OutputError
from .robot.model import SIDES, Biped

V1_BASE = ["base_x", "base_y", "base_z", "base_qw", "base_qx", "base_qy", "base_qz",
           "base_vx", "base_vy", "base_vz", "base_wx", "base_wy", "base_wz"]
AXES = ("x", "y", "z")


def joint_columns(biped: Biped) -> list[str]:
    cols = []
    for prefix in ("q_", "dq_", "tau_"):
        cols += [prefix + n for n in biped.joint_names]
    return cols


class RunLog:
    """Chunked Parquet writer; call :meth:`append` per sample, :meth:`close` at the end."""

    def __init__(self, folder: str | Path, *, flush_every: int = 1000) -> None:
        self.folder = Path(folder)
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            probe = self.folder / ".write-test"
            probe.write_text("")
            probe.unlink()
        except OSError as exc:
            raise OutputError(f"cannot write the log folder {self.folder}: {exc.strerror}") from None
        self.flush_every = int(flush_every)
        self._rows: list[Mapping[str, Any]] = []
        self._part = 0
        self.n_rows = 0

    def append(self, row: Mapping[str, Any]) -> None:
        self._rows.append(row)
        self.n_rows += 1
        if len(self._rows) >= self.flush_every:
            self.flush()

    def flush(self) -> None:
        if not self._rows:
            return
        import pandas as pd

        frame = pd.DataFrame.from_records(self._rows)
        path = self.folder / f"part-{self._part:05d}.parquet"
        tmp = path.with_suffix(".tmp")
        try:
            frame.to_parquet(tmp, index=False)
            tmp.replace(path)
        except OSError as exc:
            raise OutputError(f"cannot write {path}: {exc.strerror}") from None
        self._part += 1
        self._rows = []

    def close(self) -> None:
        self.flush()

    def __enter__(self) -> "RunLog":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def read_log(folder: str | Path):
    """Read every complete part of a run log (``DIR`` or ``DIR/log``) as one DataFrame."""
    import pandas as pd

    folder = Path(folder)
    if (folder / "log").is_dir():
        folder = folder / "log"
    parts = sorted(folder.glob("part-*.parquet"))
    if not parts:
        raise OutputError(f"no log parts in {folder}")
    frames = []
    for p in parts:
        try:
            frames.append(pd.read_parquet(p))
        except Exception:  # a part being written when the process died: skip it
            continue
    return pd.concat(frames, ignore_index=True)


class PlantRecorder:
    """Builds one log row from the plant state (world frame, SI units)."""

    def __init__(self, biped: Biped) -> None:
        self.biped = biped
        self._pdata = biped.create_data()
        self._qcols = ["q_" + n for n in biped.joint_names]
        self._dqcols = ["dq_" + n for n in biped.joint_names]
        self._taucols = ["tau_" + n for n in biped.joint_names]

    def row(self, d, *, stance: str | None = None, extra: Mapping[str, Any] | None = None) -> dict:
        """Row for plant data ``d``; ``stance`` defaults to the foot in contact (the one
        carrying more weight if both, ``none`` if neither)."""
        b = self.biped
        q, v = d.q, d.v
        row: dict[str, Any] = {"time": d.t}
        qa, dqa, ta = q[b.idx_q], v[b.idx_v], d.tau[b.idx_v]
        for i in range(len(b.joint_names)):
            row[self._qcols[i]] = float(qa[i])
            row[self._dqcols[i]] = float(dqa[i])
            row[self._taucols[i]] = float(ta[i])
        R = pin.Quaternion(q[6], q[3], q[4], q[5]).matrix()
        vw = R @ v[0:3]
        row.update(base_x=q[0], base_y=q[1], base_z=q[2], base_qw=q[6], base_qx=q[3],
                   base_qy=q[4], base_qz=q[5], base_vx=vw[0], base_vy=vw[1], base_vz=vw[2],
                   base_wx=v[3], base_wy=v[4], base_wz=v[5])
        fz = []
        for i, side in enumerate(SIDES):
            f = d.foot_force(i)
            diag = d.foot_diag(i)
            pt = d.foot_point(i)
            contact = d.foot_in_contact(i)
            for k, ax in enumerate(AXES):
                row[f"{side}_grf_{ax}"] = float(f[k])
                row[f"{side}_intrusion_{ax}"] = float(diag[2 + k]) if contact else 0.0
                row[f"{side}_p{ax}"] = float(pt[k])
            row[f"{side}_contact"] = int(contact)
            row[f"{side}_depth"] = float(diag[0]) if contact else 0.0
            row[f"{side}_pitch"] = float(diag[5])
            row[f"{side}_cap_z"] = float(diag[1])
            fz.append(float(f[2]) if contact else -np.inf)
        if stance is None:
            stance = "none" if max(fz) == -np.inf else SIDES[int(np.argmax(fz))]
        row["stance"] = stance
        for ax in AXES:
            row[f"grf_{ax}"] = row[f"{stance}_grf_{ax}"] if stance != "none" else 0.0
            row[f"intrusion_{ax}"] = row[f"{stance}_intrusion_{ax}"] if stance != "none" else 0.0
        pin.centerOfMass(b.model, self._pdata, q, v)
        c, vc = self._pdata.com[0], self._pdata.vcom[0]
        row.update(com_x=c[0], com_y=c[1], com_z=c[2], com_vx=vc[0], com_vy=vc[1], com_vz=vc[2])
        if extra:
            row.update(extra)
        return row


__all__ = ["RunLog", "read_log", "PlantRecorder", "joint_columns", "V1_BASE"]

