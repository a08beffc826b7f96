"""The frames a lying robot may join a library motion at, and the posture metric over them.

Every row of every motion's lying-to-sitting phase is a candidate frame. For an arbitrary lying
posture we want the frame nearest by the posture metric of paper 000 eq. (1)-(3) (root orientation
after yaw alignment, weighted joint angles); :class:`FrameIndex` holds the frames' features so that
the metric is one vectorised call (brute force here; :mod:`robot_rise.library.tree` prunes).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robot_rise.errors import FormatError
from robot_rise.library.motions import MotionLibrary
from robot_rise.model import Robot
from robot_rise.posture import quat_multiply

__all__ = ["Connection", "FrameIndex"]

_QUAT_Z = np.array([0.0, 0.0, 0.0, 1.0])


@dataclass(frozen=True)
class Connection:
    """The connecting posture chosen for a query.

    Attributes:
        motion: motion name.
        frame: row index in the motion's trajectory.
        time_s: time of that row [s].
        distance: posture distance of paper 000 eq. (1) to the query.
        evaluations: number of frame distances evaluated to find it.
    """

    motion: str
    frame: int
    time_s: float
    distance: float
    evaluations: int


@dataclass(frozen=True)
class FrameIndex:
    """Candidate frames in the metric's own coordinates (read-only arrays).

    Attributes:
        motion_names: motion per motion id.
        motion_id, frame, time_s: per frame, shape (M,).
        quat: root quaternions (w, x, y, z), shape (M, 4).
        quat_z: the same turned by pi about world z (k * q), shape (M, 4) (yaw alignment).
        joints_w: joint angles times sqrt(w^i) of eq. (3), shape (M, n).
        root_weight: w_q of eq. (1).
        sqrt_w: sqrt of the joint weights, shape (n,).
    """

    motion_names: tuple[str, ...]
    motion_id: np.ndarray
    frame: np.ndarray
    time_s: np.ndarray
    quat: np.ndarray
    quat_z: np.ndarray
    joints_w: np.ndarray
    root_weight: float
    sqrt_w: np.ndarray

    @classmethod
    def build(cls, library: MotionLibrary, robot: Robot) -> FrameIndex:
        mids, frames, times, quats, joints = [], [], [], [], []
        for k, m in enumerate(library.motions):
            tr = m.trajectory
            cols = [tr.joint_names.index(j) for j in robot.joint_names]
            rows = np.flatnonzero(tr.t <= m.connect_until_s + 1e-9)
            if tr.root is None:
                raise FormatError(f"motion {m.name}: no 'root' pose per row to index")
            mids.append(np.full(rows.size, k))
            frames.append(rows)
            times.append(tr.t[rows])
            quats.append(tr.root[rows, 3:])
            joints.append(tr.q[rows][:, cols])
        q = np.concatenate(quats)
        q = q / np.linalg.norm(q, axis=1, keepdims=True)
        sqrt_w = np.sqrt(np.asarray(robot.metric_weights, dtype=float))
        arrays = dict(
            motion_id=np.concatenate(mids),
            frame=np.concatenate(frames),
            time_s=np.concatenate(times),
            quat=q,
            quat_z=quat_multiply(_QUAT_Z, q),
            joints_w=np.concatenate(joints) * sqrt_w,
        )
        for a in arrays.values():
            a.setflags(write=False)
        return cls(tuple(library.names()), root_weight=robot.root_orientation_weight, sqrt_w=sqrt_w, **arrays)

    @property
    def size(self) -> int:
        return int(self.frame.size)

    def query_features(self, quat_wxyz: np.ndarray, joints: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(unit quaternion shape (4,), weighted joints shape (n,)) of a query posture."""
        q = np.asarray(quat_wxyz, dtype=float)
        return q / np.linalg.norm(q), np.asarray(joints, dtype=float) * self.sqrt_w

    def distances(self, q: np.ndarray, jw: np.ndarray, rows: np.ndarray | slice = slice(None)) -> np.ndarray:
        """Paper 000 eq. (1) from a query (features) to frames ``rows``, shape (len(rows),).

        Same value as :class:`robot_rise.posture.PostureDistance`, with the yaw alignment and the
        weights precomputed per frame.
        """
        a = self.quat[rows] @ q
        b = self.quat_z[rows] @ q
        dq = np.arccos(np.minimum(np.sqrt(a * a + b * b), 1.0))
        dv = np.sqrt(np.sum((self.joints_w[rows] - jw) ** 2, axis=1))
        return self.root_weight * dq + dv

    def pairwise(self, i: int, rows: np.ndarray) -> np.ndarray:
        """Distances from frame ``i`` to frames ``rows``."""
        return self.distances(self.quat[i], self.joints_w[i], rows)

    def _connection(self, i: int, d: float, evaluations: int) -> Connection:
        return Connection(self.motion_names[self.motion_id[i]], int(self.frame[i]), float(self.time_s[i]), float(d), evaluations)

    def brute_force(self, quat_wxyz: np.ndarray, joints: np.ndarray) -> Connection:
        """Nearest frame by evaluating every frame."""
        q, jw = self.query_features(quat_wxyz, joints)
        d = self.distances(q, jw)
        i = int(np.argmin(d))
        return self._connection(i, float(d[i]), self.size)

    def features(self) -> np.ndarray:
        """Euclidean features for K-means: weighted joints and w_q times the body-frame up vector, shape (M, n + 3).

        The up vector seen from the body (third row of R) ignores yaw, like the metric does.
        """
        w, x, y, z = self.quat.T
        up = np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=1)
        return np.concatenate([self.joints_w, self.root_weight * 0.5 * up], axis=1)
