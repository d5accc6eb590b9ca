"""The compiled solver: kernels, the adaptive integrator, the stepper and solver driving it,
the dense trace of a run, and the surrogate's kernel."""
