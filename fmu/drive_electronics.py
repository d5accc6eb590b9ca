"""FMI 2.0 co-simulation slave: a high-voltage drive for a DFA (the co-simulation
example's second FMU). It produces the polarity-inversion waveforms used in practice
with the limits of a real amplifier: a finite slew rate, and a current limit, which caps
dV/dt at I_max / C for the actuator's capacitance C (an input from the actuator FMU).

mode = "reset_dc": bipolar square wave at `frequency` for `reset_time` (the paper's
charge reset, Sec. 4.2), then the DC hold at +amplitude. mode = "inversion": the
bipolar square wave throughout. mode = "dc": +amplitude throughout.
"""
import math

from pythonfmu.enums import Fmi2Causality, Fmi2Initial, Fmi2Variability
from pythonfmu.fmi2slave import Fmi2Slave
from pythonfmu.variables import Real, String

MODES = ("reset_dc", "inversion", "dc")
PARAMS = {  # name: (unit, description, start, lower bound (exclusive unless 0))
    "amplitude": ("V", "voltage amplitude", 6000.0),
    "frequency": ("Hz", "polarity inversion frequency", 30.0),
    "reset_time": ("s", "duration of the bipolar charge reset (mode reset_dc)", 3.0),
    "slew_rate": ("V/s", "amplifier slew rate limit", 5.0e6),
    "current_limit": ("A", "amplifier output current limit", 2.0e-3),
}
# the unit of every Real variable (build.py writes them into modelDescription.xml)
UNITS = {"load_capacitance": "F", "voltage": "V", "supply_current": "A", **{k: p[0] for k, p in PARAMS.items()}}


def reference(mode, t, amplitude, frequency, reset_time):
    """The ideal waveform at time t (before the amplifier's limits)."""
    bipolar = amplitude if math.floor(2.0 * frequency * t + 1e-9) % 2 == 0 else -amplitude
    if mode == "inversion" or (mode == "reset_dc" and t < reset_time - 1e-12):
        return bipolar
    return amplitude


class DriveElectronics(Fmi2Slave):
    author = "dfa-toolkit"
    description = "High-voltage drive: polarity inversion / charge reset with slew-rate and current limits"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.voltage = 0.0
        self.supply_current = 0.0
        self.load_capacitance = 0.0
        self.mode = "reset_dc"
        self.register_variable(Real("load_capacitance", causality=Fmi2Causality.input,
                                    variability=Fmi2Variability.continuous,
                                    description="capacitance of the driven actuator [F]", setter=self._set_cap))
        self.register_variable(Real("voltage", causality=Fmi2Causality.output, variability=Fmi2Variability.continuous,
                                    initial=Fmi2Initial.calculated, description="output voltage [V]"))
        self.register_variable(Real("supply_current", causality=Fmi2Causality.output,
                                    variability=Fmi2Variability.continuous, initial=Fmi2Initial.calculated,
                                    description="capacitive charging current C dV/dt over the last step [A]"))
        self.register_variable(String("mode", causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed,
                                      initial=Fmi2Initial.exact, description="waveform: " + ", ".join(MODES),
                                      setter=self._set_mode))
        for name, (unit, text, start) in PARAMS.items():
            setattr(self, name, start)
            self.register_variable(Real(name, causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed,
                                        initial=Fmi2Initial.exact, description=f"{text} [{unit}]",
                                        setter=self._param_setter(name)))

    def _param_setter(self, name):
        def put(value):
            if not (math.isfinite(value) and value > 0 or (name == "reset_time" and value == 0)):
                raise ValueError(f"{name}: got {value!r}, expected a finite number > 0 ({PARAMS[name][0]})")
            setattr(self, name, value)
        return put

    def _set_mode(self, value):
        if value not in MODES:
            raise ValueError(f"mode: got {value!r}, expected one of {', '.join(MODES)}")
        self.mode = value

    def _set_cap(self, value):
        if not (math.isfinite(value) and value >= 0):
            raise ValueError(f"load_capacitance: got {value!r}, expected a finite number >= 0 (F)")
        self.load_capacitance = value

    def do_step(self, current_time, step_size):
        # the ideal waveform is sampled at the step end (zero-order hold over the step)
        target = reference(self.mode, current_time + step_size, self.amplitude, self.frequency, self.reset_time)
        rate = self.slew_rate
        if self.load_capacitance > 0:
            rate = min(rate, self.current_limit / self.load_capacitance)
        dv = max(-rate * step_size, min(rate * step_size, target - self.voltage))
        self.voltage += dv
        self.supply_current = self.load_capacitance * dv / step_size
        return True
