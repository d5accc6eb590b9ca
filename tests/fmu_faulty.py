"""Test-only FMU slave: the actuator with a fault injected at a chosen entry point, to
show that the FMU binary (fmu/c/fmi2_python.c) survives every kind of Python failure.

The fault is read at every call from `fault.txt` beside this module (the FMU's
resources), so that one host process can switch faults between calls: one line
"<entry> <mode>", entry one of ENTRIES, mode "raise" (default) or one of the wrong
results below; a missing or empty file means no fault. Packed with
fmu.build.build_actuator_variant (tests/fmu_cases.py).
"""
import os

from dfa_actuator import DFAActuator

_HERE = os.path.dirname(os.path.abspath(__file__))
ENTRIES = ("__init__", "setup_experiment", "enter_initialization_mode", "exit_initialization_mode", "do_step",
           "terminate", "get_real", "get_integer", "get_boolean", "get_string", "set_real", "set_integer",
           "set_boolean", "set_string", "_get_fmu_state", "_set_fmu_state", "_fmu_state_to_bytes",
           "_fmu_state_from_bytes", "log_queue")


class InjectedFault(RuntimeError):
    pass


def _fault(entry):
    """The mode of the fault at `entry`, or None. Raises for mode "raise"."""
    try:
        with open(os.path.join(_HERE, "fault.txt")) as f:
            words = f.read().split()
    except OSError:
        return None
    if not words or words[0] != entry:
        return None
    mode = words[1] if len(words) > 1 else "raise"
    if mode == "raise":
        raise InjectedFault(f"injected fault in {entry}")
    return mode


def _wrong(mode, good, n):
    """A getter's wrong result: of the wrong type, the wrong length, or no list at all."""
    return {"wrong_type": [object()] * n, "wrong_length": list(good) + list(good[:1]) + [good[0] if good else 0],
            "not_a_list": 42, "none": None}.get(mode, good)


class _BadMessage:
    """A log message whose every attribute is wrong."""
    status = "not a status"
    category = 7

    @property
    def msg(self):
        raise RuntimeError("this message cannot be read")


class _ClearingMessage:
    """A log message that empties the queue while it is read."""

    def __init__(self, queue):
        self.queue, self.category, self.msg = queue, "logAll", "a message that clears the queue"

    @property
    def status(self):
        self.queue.clear()
        return 0


class FaultyActuator(DFAActuator):
    def __init__(self, **kwargs):
        _fault("__init__")
        super().__init__(**kwargs)

    def setup_experiment(self, start_time, stop_time=None, tolerance=None):
        _fault("setup_experiment")
        return super().setup_experiment(start_time, stop_time, tolerance)

    def enter_initialization_mode(self):
        _fault("enter_initialization_mode")
        return super().enter_initialization_mode()

    def exit_initialization_mode(self):
        _fault("exit_initialization_mode")
        return super().exit_initialization_mode()

    def _publish(self):
        # every step goes through do_step, where the faults are injected: the binary's
        # fast steps (fmi2_python.c, fast_step) never enter Python
        super()._publish()
        self._c_step_buf[0] = 0.0

    def do_step(self, current_time, step_size):
        self._log_fault()
        mode = _fault("do_step")
        if mode == "solver":             # a real solver failure: too few steps allowed, landing on t + h
            self._stepper.max_steps = 1
            self._stepper.exact = True
            self._c_real_buf[0] = 6000.0
        elif self._stepper is not None:
            self._stepper.max_steps = 1_000_000
            self._stepper.exact = self.land_on_communication_points
        ok = super().do_step(current_time, step_size)
        return {"wrong_type": "yes", "none": None, "false": False}.get(mode, ok)

    def _log_fault(self):
        mode = _fault("log_queue")
        if mode == "not_a_list":
            self.log_queue = 42
        elif mode == "bad_entries":
            self.log_queue.extend([_BadMessage(), object(), _ClearingMessage(self.log_queue)])
            self.log("status out of range", 99, "logAll")

    def terminate(self):
        _fault("terminate")
        return super().terminate()

    def _getter(self, name, vrs):
        mode = _fault(name)
        good = getattr(super(), name)(vrs)
        return _wrong(mode, good, len(vrs)) if mode else good

    def get_real(self, vrs):
        return self._getter("get_real", vrs)

    def get_integer(self, vrs):
        return self._getter("get_integer", vrs)

    def get_boolean(self, vrs):
        return self._getter("get_boolean", vrs)

    def get_string(self, vrs):
        return self._getter("get_string", vrs)

    def set_real(self, vrs, values):
        _fault("set_real")
        return super().set_real(vrs, values)

    def set_integer(self, vrs, values):
        _fault("set_integer")
        return super().set_integer(vrs, values)

    def set_boolean(self, vrs, values):
        _fault("set_boolean")
        return super().set_boolean(vrs, values)

    def set_string(self, vrs, values):
        _fault("set_string")
        return super().set_string(vrs, values)

    def _get_fmu_state(self):
        _fault("_get_fmu_state")
        return super()._get_fmu_state()

    def _set_fmu_state(self, state):
        _fault("_set_fmu_state")
        return super()._set_fmu_state(state)

    @staticmethod
    def _fmu_state_to_bytes(state):
        mode = _fault("_fmu_state_to_bytes")
        return "not bytes" if mode == "wrong_type" else DFAActuator._fmu_state_to_bytes(state)

    @staticmethod
    def _fmu_state_from_bytes(data):
        mode = _fault("_fmu_state_from_bytes")
        return 42 if mode == "wrong_type" else DFAActuator._fmu_state_from_bytes(data)
