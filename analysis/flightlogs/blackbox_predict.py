"""Blackbox predictors: the decoded number plus a prediction from history or settings.

Main frames form segments: an I frame, then the P frames that follow it while the
stream stays valid. A P frame's prediction reads only the frames before it in its
segment, so the sequential part runs over the position in the segment (tens of steps,
an I frame every ~32 ms), each step vectorised across every segment and field.
"""

from __future__ import annotations

import numpy as np

from analysis.errors import LogError
from analysis.flightlogs.blackbox_header import FrameDef, Header

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

    def __init__(self, head: Header, where: str) -> None:
        i_def, p_def = head.frames["I"], head.frames["P"]
        for letter, fdef, ok in (("I", i_def, _MAIN_OK_I), ("P", p_def, _MAIN_OK_P)):
            for name, pred in zip(fdef.names, fdef.predictor, strict=True):
                if pred not in ok:
                    raise LogError(f"{where}: field {name} of {letter} frames uses predictor "
                                   f"{pred} ({PREDICTOR_NAMES.get(pred, 'unknown')}), which "
                                   "this decoder does not read in main frames")
        self.i_def, self.p_def = i_def, p_def
        motor = head.ints("motorOutput")
        minthrottle = head.int("minthrottle", 0)
        self.const = {MINTHROTTLE: minthrottle, P1500: 1500, VBATREF: head.int("vbatref", 0),
                      MINMOTOR: motor[0] if motor else minthrottle}
        self.motor0 = i_def.names.index("motor[0]") if "motor[0]" in i_def.names else -1
        for fdef, letter in ((i_def, "I"), (p_def, "P")):
            if MOTOR_0 in fdef.predictor and self.motor0 < 0:
                raise LogError(f"{where}: {letter} frames predict from motor[0], which the "
                               "header does not define")
        self.steps = _inc_steps(*_intervals(head))
        self.signed = np.array(i_def.signed, bool)

    def _wrap(self, v: np.ndarray) -> np.ndarray:
        """32-bit fields: int32 if signed, uint32 if not (as the firmware stores them)."""
        u = v & 0xFFFFFFFF
        return np.where(self.signed, ((v + (1 << 31)) & 0xFFFFFFFF) - (1 << 31), u)

    def _consts(self, fdef: FrameDef) -> np.ndarray:
        return np.array([self.const.get(p, 0) for p in fdef.predictor], np.int64)

    def apply(self, m: np.ndarray, is_i: np.ndarray, seg_pos: np.ndarray) -> None:
        """Predict in place. ``m``: raw values (main frames in file order, segments
        consecutive); ``is_i``: I rows; ``seg_pos``: each row's place in its segment."""
        i_pred = np.array(self.i_def.predictor)
        rows = np.flatnonzero(is_i)
        v = m[rows] + self._consts(self.i_def)
        if self.motor0 >= 0:
            v[:, i_pred == MOTOR_0] += v[:, self.motor0][:, None]
        m[rows] = self._wrap(v)
        p_pred = np.array(self.p_def.predictor)
        prev = np.flatnonzero(p_pred == PREVIOUS)
        line = np.flatnonzero(p_pred == STRAIGHT_LINE)
        avg = np.flatnonzero(p_pred == AVERAGE_2)
        inc = np.flatnonzero(p_pred == INC)
        m0 = np.flatnonzero(p_pred == MOTOR_0)
        consts = self._consts(self.p_def)
        if len(seg_pos) == 0:
            return
        order = np.argsort(seg_pos, kind="stable")
        counts = np.bincount(seg_pos)
        bounds = np.concatenate([[0], np.cumsum(counts)])
        steps = self.steps
        for j in range(1, len(counts)):
            r = order[bounds[j]:bounds[j + 1]]
            if len(r) == 0:
                continue
            p1 = m[r - 1]
            p2 = m[r - 2] if j >= 2 else p1
            v = m[r] + consts
            v[:, prev] += p1[:, prev]
            v[:, line] += 2 * p1[:, line] - p2[:, line]
            s = p1[:, avg] + p2[:, avg]
            v[:, avg] += s // 2 + ((s < 0) & (s & 1 == 1))  # C division: toward zero
            v[:, inc] += p1[:, inc] + steps[p1[:, inc] % len(steps)]
            if len(m0):
                v[:, m0] += v[:, self.motor0][:, None]
            m[r] = self._wrap(v)
