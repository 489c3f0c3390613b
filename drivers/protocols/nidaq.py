"""Registry entries of NI-DAQmx devices: ``nidaq://<device>/<channels>``.

The analog inputs (load cell ``ai0``, power ``ai1,ai2``) and the hall counter (rpm,
``ctr0``) of one device share one hardware-timed task, planned from every role of the rig
on that device; the ESC pulse train runs on a counter output (``nidaq://Dev1/ctr1``).
"""

from __future__ import annotations

from typing import Any
from urllib.parse import urlsplit

from drivers.contracts import Esc, Sensor
from drivers.device_options import DeviceUrl
from drivers.errors import DeviceError
from drivers.registry import backend, register

EXAMPLE = "nidaq://<device>/<channel>"
SUMMARY = "NI-DAQmx channels"


def _device(spec: DeviceUrl) -> str:
    device = urlsplit(spec.url).netloc
    if not device:
        raise spec.fail("", "expected nidaq://<device>/<channel>, e.g. nidaq://Dev1/ai0")
    return device


def _channels(spec: DeviceUrl) -> list[str]:
    text = spec.path.strip("/") or spec.channel
    if not text:
        raise spec.fail("", "expected nidaq://<device>/<channel>, e.g. nidaq://Dev1/ai0")
    return [c.strip() for c in text.replace(":", ",").split(",") if c.strip()]


def _hub(ctx: Any, device: str, spec: DeviceUrl) -> Any:
    """One acquisition task per device, holding every sensor role of the rig on it."""
    def make() -> Any:
        ni = backend("ni_daq", spec)
        specs = [s for s in ctx.specs.values()
                 if s.scheme == "nidaq" and s.role != "esc" and _device(s) == device] or [spec]
        ai: list[Any] = []
        counter = None
        rates = set()
        for s in specs:
            rates.add(s.number("rate_hz", 25_000.0, lo=1.0, hi=2_000_000.0))
            chans = _channels(s)
            if s.role == "rpm":
                if len(chans) != 1 or not chans[0].startswith("ctr"):
                    raise s.fail("", "the hall sensor needs one counter, e.g. nidaq://Dev1/ctr0")
                counter = f"{device}/{chans[0]}"
                continue
            want = {"load_cell": 1, "power": 2}[s.role]
            if len(chans) != want or not all(c.startswith("ai") for c in chans):
                raise s.fail("", f"{s.role} needs {want} analog input(s), e.g. "
                                 + ("nidaq://Dev1/ai0" if want == 1 else "nidaq://Dev1/ai1,ai2"))
            term = s.text("terminal", "DEFAULT")
            lo = s.number("min_v", -10.0, lo=-100.0, hi=100.0)
            hi = s.number("max_v", 10.0, lo=-100.0, hi=100.0)
            ai += [ni.AiChannel(f"{device}/{c}", f"{s.role}_{c}", lo, hi, term) for c in chans]
        if len(rates) > 1:
            raise spec.fail("rate_hz", f"all channels of {device} share one sample clock; got "
                                       f"rates {sorted(rates)}")
        if not ai:
            raise spec.fail("", f"{device}: the counter runs on the analog-input sample clock; "
                                "the rig needs an analog input (load cell) on the same device")
        try:
            acq = ni.NiAcquisition(ni.AcquisitionConfig(device, tuple(ai), rates.pop(), counter),
                                   clock=ctx.clock)
        except DeviceError:
            raise
        except Exception as exc:  # nidaqmx without the NI driver raises its own types
            raise DeviceError(f"NI-DAQmx {device}: {type(exc).__name__}: {exc}") from None
        return ni.NiHub(acq)

    # closed with the context too: a role refused after the task exists (a missing
    # calibration key) never registers with the hub, whose last release would close it
    return ctx.shared(("nidaq", device), make, close=lambda hub: hub.acq.close())


@register("nidaq", None, ("load_cell", "power", "rpm"), summary=SUMMARY, example=EXAMPLE)
def ni_sensor(ctx: Any, spec: DeviceUrl) -> Sensor:
    ni = backend("ni_daq", spec)
    hub = _hub(ctx, _device(spec), spec)
    for key in ("rate_hz", "terminal", "min_v", "max_v"):
        spec.raw(key)
    chans = _channels(spec)
    cal = spec.calibration

    def need(key: str) -> float:
        if key not in cal:
            raise DeviceError(f"{spec.where} calibration.{key}: missing; the NI backend "
                              "needs it to convert volts")
        return float(cal[key])

    if spec.role == "load_cell":
        return ni.load_cell(hub, f"load_cell_{chans[0]}", need("scale_n_per_v"),
                            float(cal.get("offset_v", 0.0)), url=spec.url)
    if spec.role == "power":
        return ni.power_sensor(hub, f"power_{chans[0]}", f"power_{chans[1]}",
                               need("current_mv_per_a"), need("voltage_mv_per_v"),
                               float(cal.get("current_offset_mv", 0.0)), url=spec.url)
    timeout = spec.number("timeout_s", 0.25, lo=0.01, hi=10.0)
    return ni.rpm_sensor(hub, int(need("magnets")), timeout, url=spec.url)


@register("nidaq", None, ("esc",), summary=SUMMARY, example=EXAMPLE)
def ni_esc(ctx: Any, spec: DeviceUrl) -> Esc:
    ni = backend("ni_daq", spec)
    chans = _channels(spec)
    if len(chans) != 1 or not chans[0].startswith("ctr"):
        raise spec.fail("", "the ESC pulse train needs one counter output, e.g. "
                            "nidaq://Dev1/ctr1")
    e = ctx.rig.esc
    settings = ni.PwmSettings(f"{_device(spec)}/{chans[0]}", e.frame_rate_hz, e.min_us,
                              e.max_us, e.idle_us,
                              spec.number("host_timeout_s", 0.5, lo=0.02, hi=10.0),
                              spec.number("dead_host_s", 0.25, lo=0.01, hi=10.0))
    try:
        esc = ni.NiPwmEsc(settings, url=spec.url)
    except DeviceError:
        raise
    except Exception as exc:  # nidaqmx without the NI driver raises its own types
        raise DeviceError(f"NI-DAQmx {settings.counter}: {type(exc).__name__}: {exc}") \
            from None
    ctx.answers[spec.role] = f"counter output {settings.counter} running"
    return esc
