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

import math
import warnings
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import pinocchio as pin

from .columns import (AXES, BASE_COLUMNS, COM_POSITION, COM_VELOCITY, GRF_COLUMNS,
                      INTRUSION_COLUMNS, LOG_DIR, STANCE, TIME, foot_column, joint_columns,
                      log_part_name)
from .dynamics.plant import readout_offsets
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
        # one gather from [readout (the plant data's read-out vector) | R·v_lin | c | ċ |
        # t, 0] gives every number of the row in row order: time, the joint block (per
        # joint q, dq, τ), the base (position, quaternion (w, x, y, z) from q's
        # (x, y, z, w), linear velocity in W, angular velocity in B), per foot its 13 values
        # (per axis grf, intrusion, contact point; contact, depth, pitch, cap_z), the
        # stance foot's grf and intrusion per axis, the CoM block. Intrusion and depth of a
        # foot off the ground, and the copies for stance "none", read the 0 — hence one
        # index array per (left in contact, right in contact, stance).
        nq, nv, na = biped.model.nq, biped.model.nv, len(biped.joint_names)
        off = readout_offsets(nq, nv, na)
        self._nq, self._nv = nq, nv
        o_v, o_tau, o_rv = off["v"], off["tau_a"], off["size"]
        o_com, o_t = o_rv + 3, o_rv + 9
        o_zero = o_t + 1
        head = [o_t]
        head += [k for i in range(nj) for k in (int(biped.idx_q[i]), o_v + int(biped.idx_v[i]),
                                                o_tau + i)]
        head += [0, 1, 2, 6, 3, 4, 5, o_rv, o_rv + 1, o_rv + 2, o_v + 3, o_v + 4, o_v + 5]
        #: where the row's contact columns (ints) and the stance column go
        self._contact_at = (len(head) + 9, len(head) + 22)
        self._stance_at = len(head) + 26
        # contact flags and vertical forces, read first (the default stance)
        self._probe = np.array([off["contact"], off["contact"] + 1, off[0, "force"] + 2,
                                off[1, "force"] + 2], dtype=np.intp)

        def foot_block(foot: int, contact: bool) -> list[int]:
            f, pt, dg = off[foot, "force"], off[foot, "point"], off[foot, "diag"]
            z = o_zero
            return ([f, dg + 2, pt, f + 1, dg + 3, pt + 1, f + 2, dg + 4, pt + 2,
                     off["contact"] + foot, dg, dg + 5, dg + 1] if contact else
                    [f, z, pt, f + 1, z, pt + 1, f + 2, z, pt + 2, off["contact"] + foot, z,
                     dg + 5, dg + 1])

        self._takes = {}
        for c0 in (False, True):
            for c1 in (False, True):
                blocks = (foot_block(0, c0), foot_block(1, c1))
                for stance in (*SIDES, "none"):
                    b = blocks[SIDES.index(stance)] if stance != "none" else [o_zero] * 8
                    copies = [b[0], b[1], b[3], b[4], b[6], b[7]]
                    take = head + blocks[0] + blocks[1] + copies + list(range(o_com, o_com + 6))
                    self._takes[c0, c1, stance] = np.array(take, dtype=np.intp)

    def row(self, d, *, stance: str | None = None, extra: Mapping[str, Any] | None = None) -> dict:
        """Row for plant data ``d``; ``stance`` defaults to the foot in contact (the one
        carrying more weight if both, ``none`` if neither).

        Columns in this order: time, per joint ``q, dq, tau``, the base, per foot (per axis
        grf, intrusion, contact point; contact, depth, pitch, cap_z), stance, the stance
        foot's grf and intrusion, the CoM, then ``extra``. Values are Python floats (ints
        for ``contact``; intrusion and depth 0 off the ground), gathered from the plant
        data's read-out vector (``d.readout()``,
        :func:`~granular_mpc.dynamics.plant.readout_offsets`), the time and the CoM in one
        gather and one ``tolist``.

        Args:
            d: plant data offering ``t`` [s] and ``readout()``
                (:class:`~granular_mpc.dynamics.plant.PlantData`,
                :class:`~granular_mpc.dynamics.fast_plant.FastPlantData`).
            stance: ``left``, ``right`` or ``none``; default as above.
            extra: further columns, appended in their order.

        Raises:
            ValueError: ``stance`` is not one of the three.
        """
        b = self.biped
        r = d.readout()
        nq = self._nq
        q, v = r[:nq], r[nq:nq + self._nv]
        pdata = self._pdata
        # the CoM pass runs the forward kinematics: the free flyer's placement is the
        # trunk's rotation, the same numbers as matrix_from_quat_xyzw(q[3:7]) bit for bit
        com = pin.centerOfMass(b.model, pdata, q, v)       # pdata.com[0]
        R = (np.ascontiguousarray(pdata.oMi[1].rotation) if self._free_flyer
             else matrix_from_quat_xyzw(q[3:7]))
        c0, c1, fz0, fz1 = r[self._probe].tolist()
        c0, c1 = c0 > 0.5, c1 > 0.5
        if stance is None:
            # the heavier foot in contact (np.argmax's choice: the first NaN, else the
            # first maximum), none if neither is in contact
            fz0 = fz0 if c0 else -math.inf
            fz1 = fz1 if c1 else -math.inf
            if max(fz0, fz1) == -math.inf:
                stance = "none"
            elif fz0 != fz0 or (fz1 == fz1 and fz0 >= fz1):
                stance = SIDES[0]
            else:
                stance = SIDES[1]
        take = self._takes.get((c0, c1, stance))
        if take is None:
            raise ValueError(f"stance must be one of {(*SIDES, 'none')}, not {stance!r}")
        # every number of the row in row order from one gather (see __init__)
        row_vals = np.concatenate((r, R @ v[0:3], com, pdata.vcom[0],
                                   (d.t, 0.0)))[take].tolist()
        i0, i1 = self._contact_at
        row_vals[i0], row_vals[i1] = int(c0), int(c1)
        row_vals.insert(self._stance_at, stance)
        row: dict[str, Any] = dict(zip(self._columns, row_vals))
        if extra:
            row.update(extra)
        return row


__all__ = ["RunLog", "read_log", "PlantRecorder", "LOG_PART_GLOB"]
