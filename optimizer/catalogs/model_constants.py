"""Model constants of a catalog (``catalog.toml``): defaults, parsing, validation.

The printed equations of Papers D and E leave a few modelling choices open (which battery
voltage, how long a frame arm is, whether the price sums the propellers). They are catalog
constants rather than code branches, so a catalog states the reading it was built for and
the model never special-cases a design. See docs/catalogs.md for the table of keys.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any

from optimizer.errors import CatalogError

#: Allowed values of the string-valued keys.
BATTERY_VOLTAGE_CHOICES = ("in_flight", "nominal")
ARM_LENGTH_CHOICES = ("radius", "diagonal")
MOTOR_CURRENT_CHOICES = ("winding", "battery")
CURRENT_MODEL_CHOICES = ("thesis", "drive")


#: Full-throttle thrust of all actuators over the weight that every design a sizing command
#: offers must reach (``--min-thrust-to-weight``): hover plus a control margin of 20 %, the
#: least a controller needs to hold attitude at hover. The thesis' model has no such check.
DEFAULT_MIN_THRUST_TO_WEIGHT = 1.2


@dataclass(frozen=True)
class ModelConstants:
    """Physical constants and model readings used by ``optimizer.model.design_model``.

    Defaults are the readings that reproduce Paper E's Tables E.8-E.10 (see
    docs/thesis-reproduction.md), except ``price_includes_propellers`` which follows
    the printed eq. (E.18).
    """

    #: rho in (E.1), (E.2). ISA sea level.
    air_density_kg_m3: float = 1.225
    #: g in (E.19).
    gravity_m_s2: float = 9.81
    #: m_F in (E.26): 0.045 kg/m, a 7x9x1000 mm carbon tube (Paper D section 2.6).
    frame_linear_density_kg_m: float = 0.045
    #: Cell voltage held constant during flight: 4.0 V per cell (Paper D section 2.1).
    cell_voltage_in_flight_v: float = 4.0
    #: Cell voltage used when a battery row has no ``nominal_voltage_v`` (LiPo: 3.7 V).
    cell_voltage_nominal_v: float = 3.7
    #: B_V in (E.67): "in_flight" = cells x cell_voltage_in_flight_v, "nominal" = the
    #: battery's nominal voltage (column ``nominal_voltage_v`` or cells x 3.7 V).
    battery_voltage: str = "in_flight"
    #: Motor-axis distance from the centre: "radius" = D / (2 sin(pi/N)) (adjacent
    #: propeller tips touch, Paper D assumption 1) or "diagonal" = D / sin(pi/N) (D.4's
    #: L read as the arm length).
    arm_length: str = "radius"
    #: Tip-to-tip gap Delta between neighbouring propellers (Paper D assumption 1), m.
    propeller_clearance_m: float = 0.0
    #: J_p = k m_p D^2 when a propeller row has no ``inertia_kgm2``; 1/8 = uniform disc.
    propeller_inertia_coefficient: float = 0.125
    #: Whether the total price (E.18) sums N propellers (Table E.8-E.10 prices do not).
    price_includes_propellers: bool = True
    #: If set, a design must reach this max-thrust / weight ratio at full battery voltage
    #: (steady state of eqs. (E.4)-(E.7)); None disables the check (the thesis has none).
    #: The sizing commands raise it to ``DEFAULT_MIN_THRUST_TO_WEIGHT`` unless run with
    #: ``--thesis-rules`` (``bench.store.catalogs.with_min_thrust_to_weight``).
    min_thrust_to_weight: float | None = None
    #: Which current the motor's ``max_current_a`` limits. "winding": the torque current
    #: I_w = Q / K_t + I_0 at hover, Q = W / omega (E.3), is checked ("motor winding
    #: current") besides the thesis' per-actuator battery current x18 / N (E.67,
    #: "motor current"); "battery": only the thesis' check (Papers D and E as printed).
    motor_current: str = "winding"
    #: What the battery delivers per actuator, the one current definition of a run (design
    #: current, flight time, power, current limits, the eCalc sheet and its rules):
    #: "thesis" = the propeller's shaft power at B_V, x18 / N = N x17 / B_V (E.67), a
    #: loss-free motor and ESC (Papers D and E as printed); "drive" = the motor's electric
    #: power V_m I_w at B_V, V_m = K_e omega + R I_w, I_w = Q / K_t + I_0 (E.4)-(E.7): the
    #: winding loss R I_w^2 and the no-load current drawn from the battery (lossless ESC).
    current_model: str = "thesis"

    def with_updates(self, **changes: Any) -> ModelConstants:
        """A copy with some constants replaced (validated like catalog.toml)."""
        return constants_from_mapping({**self.as_dict(), **changes}, "<constants>")

    def as_dict(self) -> dict[str, Any]:
        return {f.name: getattr(self, f.name) for f in fields(self)}


_CHOICES = {
    "battery_voltage": BATTERY_VOLTAGE_CHOICES,
    "arm_length": ARM_LENGTH_CHOICES,
    "motor_current": MOTOR_CURRENT_CHOICES,
    "current_model": CURRENT_MODEL_CHOICES,
}
_KNOWN = {f.name for f in fields(ModelConstants)}
#: Free-text keys allowed in catalog.toml (documentation only).
_TEXT_KEYS = {"name", "description", "source"}


def _number(where: str, key: str, value: Any, *, positive: bool) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise CatalogError(f"{where}: key '{key}': expected a number, got {value!r}")
    if positive and value <= 0:
        raise CatalogError(f"{where}: key '{key}': expected a number > 0, got {value!r}")
    if value < 0:
        raise CatalogError(f"{where}: key '{key}': expected a number >= 0, got {value!r}")
    return float(value)


def constants_from_mapping(data: dict[str, Any], where: str) -> ModelConstants:
    """Validate a mapping of constants (parsed TOML or keyword updates)."""
    values: dict[str, Any] = {}
    for key, value in data.items():
        if key in _TEXT_KEYS:
            if not isinstance(value, str):
                raise CatalogError(f"{where}: key '{key}': expected a string, got {value!r}")
            continue
        if key not in _KNOWN:
            known = ", ".join(sorted(_KNOWN | _TEXT_KEYS))
            raise CatalogError(f"{where}: unknown key '{key}' (known keys: {known})")
        values[key] = value
    out = ModelConstants()
    for key, value in values.items():
        default = getattr(out, key)
        if key in _CHOICES:
            if value not in _CHOICES[key]:
                allowed = ", ".join(repr(v) for v in _CHOICES[key])
                raise CatalogError(
                    f"{where}: key '{key}': expected one of {allowed}, got {value!r}"
                )
        elif isinstance(default, bool):
            if not isinstance(value, bool):
                raise CatalogError(f"{where}: key '{key}': expected true or false, got {value!r}")
        elif key == "min_thrust_to_weight":
            if value is not None:
                value = _number(where, key, value, positive=True)
        elif key == "propeller_clearance_m":
            value = _number(where, key, value, positive=False)
        else:
            value = _number(where, key, value, positive=True)
        out = replace(out, **{key: value})
    return out


def load_constants(path: Path) -> ModelConstants:
    """Read ``catalog.toml``; a missing file gives the defaults."""
    if not path.exists() and not path.is_symlink():  # a link to nowhere is not "absent"
        return ModelConstants()
    if path.exists() and not path.is_file():  # a folder, a FIFO (blocks), a device
        raise CatalogError(f"{path}: not a regular file")
    try:
        with path.open("rb") as fh:
            data = tomllib.load(fh)
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:  # bytes that are not text
        raise CatalogError(f"{path}: invalid TOML: {exc}") from None
    except OSError as exc:
        raise CatalogError(f"{path}: cannot read: {exc.strerror}") from None
    return constants_from_mapping(data, str(path))
