"""Run logs: written as the run goes, readable after any interruption.

Format (documented in ``docs/log-format.md``): a folder ``log/`` of Parquet files
``part-00000.parquet``, ``part-00001.parquet`` … (:func:`granular_mpc.columns.log_part_name`),
each a complete Parquet file holding consecutive rows. A crash, Ctrl-C or divergence loses
at most the rows not yet flushed (one chunk, ``flush_every`` rows); every part already on
disk stays readable.

The columns (names from :mod:`granular_mpc.columns`) are a superset of measurement data
format v1 (``docs/data-format.md``), so a run log is itself a valid data set for
``granular-mpc validate``:

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

import warnings
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import pinocchio as pin

from .columns import (AXES, BASE_COLUMNS, COM_POSITION, COM_VELOCITY, GRF_COLUMNS,
                      INTRUSION_COLUMNS, LOG_DIR, STANCE, TIME, foot_column, joint_columns,
                      log_part_name)
from .exceptions import OutputError
from .robot.model import SIDES, Biped
from .rotations import matrix_from_quat_xyzw

LOG_PART_GLOB = "part-*.parquet"
"""Glob pattern of the complete log parts in a log folder."""


class RunLog:
    """Chunked Parquet writer; call :meth:`append` per sample, :meth:`close` at the end.

    Args:
        folder: the log folder (created).
        flush_every: rows per part file.

    Raises:
        OutputError: the folder cannot be created or written.
    """

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
        """Add one row; a full chunk is written as the next part."""
        self._rows.append(row)
        self.n_rows += 1
        if len(self._rows) >= self.flush_every:
            self.flush()

    def flush(self) -> None:
        """Write the rows held so far as the next part (atomically: ``.tmp`` then rename).

        Raises:
            OutputError: the part cannot be written.
        """
        if not self._rows:
            return
        import pandas as pd

        frame = pd.DataFrame.from_records(self._rows)
        path = self.folder / log_part_name(self._part)
        tmp = path.with_suffix(".tmp")
        try:
            frame.to_parquet(tmp, index=False)
            tmp.replace(path)
        except OSError as exc:
            raise OutputError(f"cannot write {path}: {exc.strerror}") from None
        self._part += 1
        self._rows = []

    def close(self) -> None:
        """Write the remaining rows."""
        self.flush()

    def __enter__(self) -> "RunLog":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def read_log(folder: str | Path):
    """Read every complete part of a run log (``DIR`` or ``DIR/log``) as one DataFrame.

    The last part, if it cannot be read (being written when the process died), is
    skipped quietly. An unreadable part *before* the last one leaves a hole in the log:
    it is skipped with a warning naming the part and the gap in simulated time.

    Raises:
        OutputError: the folder holds no readable log part.
    """
    import pandas as pd

    folder = Path(folder)
    if (folder / LOG_DIR).is_dir():
        folder = folder / LOG_DIR
    parts = sorted(folder.glob(LOG_PART_GLOB))
    if not parts:
        raise OutputError(f"no log parts in {folder}")
    frames = []
    bad: list[tuple[int, Path, str]] = []
    for i, p in enumerate(parts):
        try:
            frames.append(pd.read_parquet(p))
        except Exception as exc:  # noqa: BLE001 - pyarrow raises many kinds
            bad.append((len(frames), p, type(exc).__name__))
    if not frames:
        raise OutputError(f"no readable log part in {folder} ({len(parts)} unreadable)")
    for k, p, why in bad:
        if k == len(frames) and p == parts[-1]:
            continue                    # the part being written at the end
        before = frames[k - 1][TIME].iloc[-1] if k > 0 and len(frames[k - 1]) else None
        after = frames[k][TIME].iloc[0] if k < len(frames) and len(frames[k]) else None
        gap = (f"t = {before:.3f} s to {after:.3f} s is missing" if before is not None
               and after is not None else "its rows are missing")
        warnings.warn(f"log part {p.name} cannot be read ({why}) and is skipped: {gap}",
                      stacklevel=2)
    return pd.concat(frames, ignore_index=True)


class PlantRecorder:
    """Builds one log row from the plant state (world frame, SI units).

    Args:
        biped: the robot (joint names, actuated indices, Pinocchio model for the CoM).
    """

    def __init__(self, biped: Biped) -> None:
        self.biped = biped
        self._pdata = biped.create_data()
        nj = len(biped.joint_names)
        qcols = joint_columns(biped.joint_names, "q")
        dqcols = joint_columns(biped.joint_names, "dq")
        taucols = joint_columns(biped.joint_names, "tau")
        # the joint columns interleaved per joint (q, dq, τ), the row's column order
        self._joint_cols = tuple(c for i in range(nj) for c in (qcols[i], dqcols[i], taucols[i]))
        # per foot: (grf, intrusion, contact point) column per axis, then the scalars
        self._foot = [(tuple(c for ax in AXES for c in (foot_column(side, f"grf_{ax}"),
                                                         foot_column(side, f"intrusion_{ax}"),
                                                         foot_column(side, f"p{ax}"))),
                       foot_column(side, "contact"), foot_column(side, "depth"),
                       foot_column(side, "pitch"), foot_column(side, "cap_z"))
                      for side in SIDES]
        # the stance foot's copies (grf, intrusion per axis; zero for stance "none")
        self._none_cols = tuple((c, 0.0) for pair in zip(GRF_COLUMNS, INTRUSION_COLUMNS)
                                for c in pair)
        self._com_cols = COM_POSITION + COM_VELOCITY
        self._free_flyer = biped.model.joints[1].shortname() == "JointModelFreeFlyer"
        # every column of a row but ``extra``, in row order: time, joints, base, per foot
        # (per axis grf, intrusion, contact point; contact, depth, pitch, cap_z), stance,
        # the stance foot's grf and intrusion (per axis), the CoM
        self._columns = ((TIME,) + self._joint_cols + tuple(BASE_COLUMNS)
                         + tuple(c for axis_cols, *scalars in self._foot
                                 for c in (*axis_cols, *scalars))
                         + (STANCE,) + tuple(c for c, _ in self._none_cols)
                         + tuple(self._com_cols))
        self._none_values = tuple(v for _, v in self._none_cols)
        # one gather from [q, v, τ, R·v_lin, c, ċ] (sizes nq, nv, nv, 3, 3, 3) gives, in row
        # order, the joint block (per joint q, dq, τ), the base (position, quaternion
        # (w, x, y, z) from q's (x, y, z, w), linear velocity in W, angular velocity in B)
        # and the CoM block: the values the row had element by element
        nq, nv = biped.model.nq, biped.model.nv
        o_v, o_tau, o_rv = nq, nq + nv, nq + 2 * nv
        o_com = o_rv + 3
        take = [k for i in range(nj) for k in (int(biped.idx_q[i]), o_v + int(biped.idx_v[i]),
                                               o_tau + int(biped.idx_v[i]))]
        take += [0, 1, 2, 6, 3, 4, 5, o_rv, o_rv + 1, o_rv + 2, o_v + 3, o_v + 4, o_v + 5]
        self._n_head = len(take)
        take += list(range(o_com, o_com + 6))
        self._take = np.array(take, dtype=np.intp)

    def row(self, d, *, stance: str | None = None, extra: Mapping[str, Any] | None = None) -> dict:
        """Row for plant data ``d``; ``stance`` defaults to the foot in contact (the one
        carrying more weight if both, ``none`` if neither).

        Columns in this order: time, per joint ``q, dq, tau``, the base, per foot (per axis
        grf, intrusion, contact point; contact, depth, pitch, cap_z), stance, the stance
        foot's grf and intrusion, the CoM, then ``extra``. Values are Python floats (ints
        for ``contact``), filled from whole arrays at once (one ``tolist`` per block)."""
        b = self.biped
        q, v = d.q, d.v
        pdata = self._pdata
        # the CoM pass runs the forward kinematics: the free flyer's placement is the
        # trunk's rotation, the same numbers as matrix_from_quat_xyzw(q[3:7]) bit for bit
        pin.centerOfMass(b.model, pdata, q, v)
        R = (np.ascontiguousarray(pdata.oMi[1].rotation) if self._free_flyer
             else matrix_from_quat_xyzw(q[3:7]))
        # joints, base and CoM values in row order from one gather (see __init__)
        flat = np.concatenate((q, v, d.tau, R @ v[0:3], pdata.com[0], pdata.vcom[0]))
        gathered = flat[self._take].tolist()
        n_head = self._n_head
        # the values in column order (time, joints, base, both feet, stance, the stance
        # foot's copies, CoM), collected in one list and zipped once
        vals: list = [d.t]
        vals += gathered[:n_head]
        fz = []
        copies = []     # per foot: its (grf, intrusion) per axis, the stance columns' values
        for i in range(2):
            f = d.foot_force(i).tolist()
            diag = d.foot_diag(i).tolist()
            pt = d.foot_point(i).tolist()
            if d.foot_in_contact(i):
                vals += (f[0], diag[2], pt[0], f[1], diag[3], pt[1], f[2], diag[4], pt[2],
                         1, diag[0], diag[5], diag[1])
                copies.append((f[0], diag[2], f[1], diag[3], f[2], diag[4]))
                fz.append(f[2])
            else:
                vals += (f[0], 0.0, pt[0], f[1], 0.0, pt[1], f[2], 0.0, pt[2],
                         0, 0.0, diag[5], diag[1])
                copies.append((f[0], 0.0, f[1], 0.0, f[2], 0.0))
                fz.append(-np.inf)
        if stance is None:
            stance = "none" if max(fz) == -np.inf else SIDES[int(np.argmax(fz))]
        vals.append(stance)
        vals += copies[SIDES.index(stance)] if stance != "none" else self._none_values
        vals += gathered[n_head:]
        row: dict[str, Any] = dict(zip(self._columns, vals))
        if extra:
            row.update(extra)
        return row


__all__ = ["RunLog", "read_log", "PlantRecorder", "LOG_PART_GLOB"]
