"""Blackbox predictors: the decoded number plus a prediction from history or settings.

Main frames form segments: an I frame, then the P frames that follow it while the
stream stays valid. A P frame's prediction reads only the frames before it in its
segment, so the sequential part runs over the position in the segment (tens of steps,
an I frame every ~32 ms), each step vectorised across every segment and field.
"""

from __future__ import annotations

import numpy as np

from analysis.errors import LogError
from analysis.flightlogs.blackbox_header import Header

__all__ = ["PREDICTOR_NAMES", "Predictor"]

NONE, PREVIOUS, STRAIGHT_LINE, AVERAGE_2, MINTHROTTLE, MOTOR_0, INC = 0, 1, 2, 3, 4, 5, 6
HOME_COORD, P1500, VBATREF, LAST_MAIN_FRAME_TIME, MINMOTOR = 7, 8, 9, 10, 11
PREDICTOR_NAMES = {0: "none", 1: "previous", 2: "straight line", 3: "average 2",
                   4: "minthrottle", 5: "motor[0]", 6: "increment", 7: "home coord",
                   8: "1500", 9: "vbatref", 10: "last main frame time", 11: "minmotor"}
_MAIN_OK_I = {NONE, MINTHROTTLE, MOTOR_0, P1500, VBATREF, MINMOTOR}
_MAIN_OK_P = _MAIN_OK_I | {PREVIOUS, STRAIGHT_LINE, AVERAGE_2, INC}


def _intervals(head: Header) -> tuple[int, int, int]:
    """(I interval, P num, P denom) in loop iterations (a bare ``P interval:N`` is 1/N)."""
    i_int = max(1, head.int("I interval", 1))
    raw = head.values.get("P interval", "1/1")
    num, _, den = raw.partition("/")
    try:
        p_num, p_den = (int(num), int(den)) if den else (1, int(num))
    except ValueError:
        p_num, p_den = 1, 1
    return i_int, max(1, p_num), max(1, p_den)


def _inc_steps(i_int: int, num: int, den: int) -> np.ndarray:
    """For each iteration mod I interval, how far the next logged iteration is."""
    i_int = min(i_int, 1 << 16)

    def logged(i: int) -> bool:
        r = i % i_int
        return r == 0 or (r + num - 1) % den < num

    steps = np.ones(i_int, np.int64)
    for r in range(i_int):
        d = 1
        while not logged(r + d) and d < i_int:
            d += 1
        steps[r] = d
    return steps


class Predictor:
    """Applies one log's I and P predictors to decoded main-frame values."""

    def __init__(self, head: Header, where: str, fields: list[int]) -> None:
        """``fields``: the main-frame fields decoded (their indices, in column order);
        a field's prediction reads only its own history, and motor[0]'s."""
        i_def, p_def = head.frames["I"], head.frames["P"]
        for letter, fdef, ok in (("I", i_def, _MAIN_OK_I), ("P", p_def, _MAIN_OK_P)):
            for k in fields:
                if fdef.predictor[k] not in ok:
                    pred = fdef.predictor[k]
                    raise LogError(f"{where}: field {fdef.names[k]} of {letter} frames uses "
                                   f"predictor {pred} ({PREDICTOR_NAMES.get(pred, 'unknown')}), "
                                   "which this decoder does not read in main frames")
        motor = head.ints("motorOutput")
        minthrottle = head.int("minthrottle", 0)
        const = {MINTHROTTLE: minthrottle, P1500: 1500, VBATREF: head.int("vbatref", 0),
                 MINMOTOR: motor[0] if motor else minthrottle}
        m0 = i_def.names.index("motor[0]") if "motor[0]" in i_def.names else -1
        self.i_pred = np.array([i_def.predictor[k] for k in fields])
        self.p_pred = np.array([p_def.predictor[k] for k in fields])
        if (MOTOR_0 in self.i_pred or MOTOR_0 in self.p_pred) and m0 not in fields:
            raise LogError(f"{where}: fields predict from motor[0], which the header does "
                           "not define")
        self.motor0 = fields.index(m0) if m0 in fields else -1
        self.i_const = np.array([const.get(int(p), 0) for p in self.i_pred], np.int64)
        self.p_const = np.array([const.get(int(p), 0) for p in self.p_pred], np.int64)
        self.steps = _inc_steps(*_intervals(head))
        self.unsigned = np.array([not i_def.signed[k] for k in fields], bool)

    def _wrap(self, v: np.ndarray) -> None:
        """Unsigned fields are uint32 in the firmware (``time`` wraps after 71.6 min)."""
        v[:, self.unsigned] &= 0xFFFFFFFF

    def apply(self, m: np.ndarray, is_i: np.ndarray, seg_pos: np.ndarray) -> None:
        """Predict in place. ``m``: raw values (main frames in file order, segments
        consecutive); ``is_i``: I rows; ``seg_pos``: each row's place in its segment."""
        rows = np.flatnonzero(is_i)
        v = m[rows] + self.i_const
        if self.motor0 >= 0:
            v[:, self.i_pred == MOTOR_0] += v[:, self.motor0][:, None]
        self._wrap(v)
        m[rows] = v
        p_pred = self.p_pred
        prev = np.flatnonzero(p_pred == PREVIOUS)
        line = np.flatnonzero(p_pred == STRAIGHT_LINE)
        avg = np.flatnonzero(p_pred == AVERAGE_2)
        inc = np.flatnonzero(p_pred == INC)
        m0 = np.flatnonzero(p_pred == MOTOR_0)
        if len(seg_pos) == 0:
            return
        counts = np.bincount(seg_pos)
        seg_len = len(counts)
        if seg_pos[0] == 0 and len(m) % seg_len == 0 and np.all(counts == len(m) // seg_len):
            # every segment equally long (an undamaged window): strided views, no gathers
            cube = m.reshape(-1, seg_len, m.shape[1])
            order = bounds = None
        else:
            cube = None
            order = np.argsort(seg_pos, kind="stable")
            bounds = np.concatenate([[0], np.cumsum(counts)])
        steps = self.steps
        for j in range(1, seg_len):
            r: np.ndarray | None = None
            if cube is not None:
                p1 = cube[:, j - 1]
                p2 = cube[:, j - 2] if j >= 2 else p1
                v = cube[:, j] + self.p_const
            else:
                assert order is not None and bounds is not None
                r = order[bounds[j]:bounds[j + 1]]
                if len(r) == 0:
                    continue
                p1 = m[r - 1]
                p2 = m[r - 2] if j >= 2 else p1
                v = m[r] + self.p_const
            v[:, prev] += p1[:, prev]
            v[:, line] += 2 * p1[:, line] - p2[:, line]
            s = p1[:, avg] + p2[:, avg]
            v[:, avg] += s // 2 + ((s < 0) & (s & 1 == 1))  # C division: toward zero
            v[:, inc] += p1[:, inc] + steps[p1[:, inc] % len(steps)]
            if len(m0):
                v[:, m0] += v[:, self.motor0][:, None]
            self._wrap(v)
            if cube is not None:
                cube[:, j] = v
            elif r is not None:
                m[r] = v
