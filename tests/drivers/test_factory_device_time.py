"""Device time stamps mapped onto the host clock (drivers/device_time.py)."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.contracts import Block, ChannelInfo, DeviceInfo
from drivers.device_time import DeviceTimeSensor
from drivers.errors import DeviceError


class Lines:
    """Blocks of (host reception time, device time) handed out one by one."""

    def __init__(self, blocks):
        self.blocks = list(blocks)

    def describe(self):
        return DeviceInfo("load_cell", "fake board", "serial://fake",
                          (ChannelInfo("thrust_n", "N", 250.0), ChannelInfo("t_s", "s", 250.0)))

    def read_block(self):
        host, dev = self.blocks.pop(0)
        return Block(np.asarray(host, float), {"thrust_n": np.zeros(len(host)),
                                               "t_s": np.asarray(dev, float)})

    def close(self):
        pass


def test_reception_jitter_is_removed_and_stamps_never_run_backwards():
    rng = np.random.default_rng(3)
    dev = np.arange(500) * 0.004  # the board prints every 4 ms
    delay = 0.0005 + rng.exponential(0.003, dev.size)  # transport + a busy host
    host = 100.0 + dev + delay
    blocks = [(host[k:k + 5], dev[k:k + 5]) for k in range(0, dev.size, 5)]
    s = DeviceTimeSensor(Lines(blocks))
    t = np.concatenate([s.read_block().t_s for _ in blocks])
    assert np.all(np.diff(t) >= 0)
    late = t[dev > 0.5]  # after the first window of lines
    # the stamps keep the device's even spacing; the offset is the smallest delay seen
    assert np.diff(late) == pytest.approx(0.004, abs=2e-4)
    assert np.all(late <= host[dev > 0.5] + 1e-12)
    assert late - (100.0 + dev[dev > 0.5]) == pytest.approx(delay.min(), abs=3e-4)
    assert np.std(np.diff(host)) > 10 * np.std(np.diff(late))


def test_micros_wrap_and_a_layout_without_device_time():
    wrap = 2**32 * 1e-6
    dev = np.array([wrap - 0.008, wrap - 0.004, 0.0, 0.004])
    s = DeviceTimeSensor(Lines([(1000.0 + np.arange(4) * 0.004 + 0.001, dev)]))
    assert np.diff(s.read_block().t_s) == pytest.approx([0.004] * 3)

    class NoTime(Lines):
        def describe(self):
            return DeviceInfo("load_cell", "fake", "serial://fake",
                              (ChannelInfo("thrust_n", "N", 1.0),))

    with pytest.raises(DeviceError, match="need a 't_s' column"):
        DeviceTimeSensor(NoTime([]))
