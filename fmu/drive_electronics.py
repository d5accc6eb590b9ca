"""FMI 2.0 co-simulation slave: a high-voltage drive for a DFA (the co-simulation
example's second FMU). It produces the polarity-inversion waveforms used in practice
with the limits of a real amplifier: a finite slew rate, and a current limit, which caps
dV/dt at I_max / C for the actuator's capacitance C (an input from the actuator FMU).

mode = "reset_dc": bipolar square wave at `frequency` for `reset_time` (the paper's
charge reset, Sec. 4.2), then the DC hold at +amplitude. mode = "inversion": the
bipolar square wave throughout. mode = "dc": +amplitude throughout.

mode = "protocol" (only in a drive built with a protocol file, `dfa fmu build --system
--drive DRIVE.toml`): the protocol's voltage, piecewise linear between its breakpoints
(resources/drive_protocol.json, written at build time), held at its last value after
its end; time 0 of the protocol is time 0 of the simulation. Such a drive starts in
this mode, and its output starts at the protocol's value at the start time.

Start values the build chose (resources/start_values.json: name -> value) are applied at
instantiation through the same checks as a host's set. This module imports no dfa_model.
"""
import bisect
import json
import math
import os

from pythonfmu.enums import Fmi2Causality, Fmi2Initial, Fmi2Variability
from pythonfmu.fmi2slave import Fmi2Slave
from pythonfmu.variables import Real, String

MODES = ("reset_dc", "inversion", "dc")
PROTOCOL_MODE = "protocol"
PROTOCOL_FILE = "drive_protocol.json"    # the protocol's breakpoints (fmu/ssp.py writes it)
START_FILE = "start_values.json"         # start values chosen at build time (fmu/build.py writes it)
PARAMS = {  # name: (unit, description, start, 0 allowed); each is finite and > 0 (or 0 where allowed)
    "amplitude": ("V", "voltage amplitude", 6000.0, False),
    "frequency": ("Hz", "polarity inversion frequency", 30.0, False),
    "reset_time": ("s", "duration of the bipolar charge reset (mode reset_dc)", 3.0, True),
    "slew_rate": ("V/s", "amplifier slew rate limit", 5.0e6, False),
    "current_limit": ("A", "amplifier output current limit", 2.0e-3, False),
}
# the unit of every Real variable (build.py writes them into modelDescription.xml)
UNITS = {"load_capacitance": "F", "voltage": "V", "supply_current": "A", **{k: p[0] for k, p in PARAMS.items()}}
# [min, max] (None: unbounded) of the parameters and the input, from the setters' checks
# (build.py writes them into modelDescription.xml; FMI's min is inclusive, a setter
# refuses 0 where it must be > 0)
RANGES = {"load_capacitance": (0.0, None), **{k: (0.0, None) for k in PARAMS}}


def reference(mode, t, amplitude, frequency, reset_time):
    """The ideal waveform at time t (before the amplifier's limits)."""
    bipolar = amplitude if math.floor(2.0 * frequency * t + 1e-9) % 2 == 0 else -amplitude
    if mode == "inversion" or (mode == "reset_dc" and t < reset_time - 1e-12):
        return bipolar
    return amplitude


class PlayedProtocol:
    """A protocol's voltage from its breakpoints: v0[i] + slope[i] (t - t[i]) on
    [t[i], t[i+1]] (dfa_model.waveforms.Piecewise, evaluated the same way), the end
    value after t[-1], the start value before t[0]."""

    def __init__(self, data, where):
        try:
            t, v0, slope = ([float(x) for x in data[k]] for k in ("t", "v0", "slope"))
            self.duration = float(data["duration"])
            self.source = str(data.get("source", "protocol"))
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"{where}: expected lists t, v0, slope and a duration ({exc})") from None
        n = len(v0)
        if n < 1 or len(slope) != n or len(t) != n + 1:
            raise ValueError(f"{where}: expected len(t) = len(v0) + 1 = len(slope) + 1 >= 2, got {len(t)}, "
                             f"{len(v0)}, {len(slope)}")
        if not all(math.isfinite(x) for x in (*t, *v0, *slope, self.duration)):
            raise ValueError(f"{where}: a breakpoint or value is not finite")
        if any(b < a for a, b in zip(t, t[1:])):
            raise ValueError(f"{where}: the breakpoints t are not in increasing order")
        self.t, self.v0, self.slope = t, v0, slope

    def __call__(self, t):
        tt = self.t
        if t >= tt[-1]:
            i, t = len(self.v0) - 1, tt[-1]
        elif t <= tt[0]:
            i, t = 0, tt[0]
        else:
            i = bisect.bisect_right(tt, t) - 1
        return self.v0[i] + self.slope[i] * (t - tt[i])


def read_json(folder, name):
    """resources/<name> as JSON, or None when the build wrote none."""
    path = os.path.join(folder, name) if folder else None
    if path is None or not os.path.exists(path):
        return None
    with open(path, encoding="utf-8") as f:
        return json.load(f)


class DriveElectronics(Fmi2Slave):
    author = "dfa-toolkit"
    description = "High-voltage drive: polarity inversion / charge reset with slew-rate and current limits"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        data = read_json(self.resources, PROTOCOL_FILE)
        self._protocol = None if data is None else PlayedProtocol(data, f"resources/{PROTOCOL_FILE}")
        self._modes = MODES + ((PROTOCOL_MODE,) if self._protocol else ())
        self._start_time = 0.0
        self.voltage = 0.0
        self.supply_current = 0.0
        self.load_capacitance = 0.0
        self.mode = "reset_dc"
        modes = ", ".join(self._modes)
        if self._protocol:
            p = self._protocol
            modes += f" (protocol: {p.source}, {p.duration:g} s, built in)"
        self.register_variable(Real("load_capacitance", causality=Fmi2Causality.input,
                                    variability=Fmi2Variability.continuous,
                                    description="capacitance of the driven actuator [F]", setter=self._set_cap))
        self.register_variable(Real("voltage", causality=Fmi2Causality.output, variability=Fmi2Variability.continuous,
                                    initial=Fmi2Initial.calculated, description="output voltage [V]"))
        self.register_variable(Real("supply_current", causality=Fmi2Causality.output,
                                    variability=Fmi2Variability.continuous, initial=Fmi2Initial.calculated,
                                    description="capacitive charging current C dV/dt over the last step [A]"))
        self.register_variable(String("mode", causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed,
                                      initial=Fmi2Initial.exact, description="waveform: " + modes,
                                      setter=self._set_mode))
        for name, (unit, text, start, _) in PARAMS.items():
            setattr(self, name, start)
            self.register_variable(Real(name, causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed,
                                        initial=Fmi2Initial.exact, description=f"{text} [{unit}]",
                                        setter=self._param_setter(name)))
        start = read_json(self.resources, START_FILE)
        if start is not None:
            by_name = {v.name: v for v in self.vars.values()}
            for name, value in start.items():
                if name not in by_name or by_name[name].causality != Fmi2Causality.parameter:
                    raise ValueError(f"resources/{START_FILE}: {name}: not a parameter of this FMU")
                by_name[name].setter(value)

    def _param_setter(self, name):
        def put(value):
            unit, _, _, zero = PARAMS[name]
            if not (math.isfinite(value) and value > 0 or (zero and value == 0)):
                raise ValueError(f"{name}: got {value!r}, expected a finite number {'>=' if zero else '>'} 0 ({unit})")
            setattr(self, name, value)
        return put

    def _set_mode(self, value):
        if value not in self._modes:
            hint = " ('protocol' needs a drive built with a protocol file: dfa fmu build --system --drive FILE)" \
                if value == PROTOCOL_MODE else ""
            raise ValueError(f"mode: got {value!r}, expected one of {', '.join(self._modes)}{hint}")
        self.mode = value

    def _set_cap(self, value):
        if not (math.isfinite(value) and value >= 0):
            raise ValueError(f"load_capacitance: got {value!r}, expected a finite number >= 0 (F)")
        self.load_capacitance = value

    def _reference(self, t):
        if self.mode == PROTOCOL_MODE:
            return self._protocol(t)
        return reference(self.mode, t, self.amplitude, self.frequency, self.reset_time)

    def setup_experiment(self, start_time, stop_time, tolerance):
        self._start_time = start_time

    def exit_initialization_mode(self):
        # the protocol gives the drive's voltage from its start: the output starts there
        # (a master that exchanges the initial outputs hands it to the actuator at once)
        if self.mode == PROTOCOL_MODE:
            self.voltage = self._protocol(self._start_time)

    def do_step(self, current_time, step_size):
        # the ideal waveform is sampled at the step end (zero-order hold over the step)
        target = self._reference(current_time + step_size)
        rate = self.slew_rate
        if self.load_capacitance > 0:
            rate = min(rate, self.current_limit / self.load_capacitance)
        reach = rate * step_size
        old = self.voltage
        # within reach: the target itself (old + (target - old) can miss it by an ulp)
        self.voltage = target if abs(target - old) <= reach else old + math.copysign(reach, target - old)
        self.supply_current = self.load_capacitance * (self.voltage - old) / step_size
        return True
