"""TR-BDF2's coefficients, the integrator's status codes, and where the integrator
(integrator.py) keeps its state between its pieces (integrator, stops, records): named
slots of a few small arrays, so that the pieces are separate compiled functions that share
the stepper's state without long argument lists.
"""
from __future__ import annotations

import math

GAMMA = 2.0 - math.sqrt(2.0)
DG = GAMMA / 2.0
WTR = math.sqrt(2.0) / 4.0
# b - b_hat of the embedded companion: [(4w-1)/3, -1/3, 2d/3]
E0 = (4.0 * WTR - 1.0) / 3.0
E1 = -1.0 / 3.0
E2 = 2.0 * DG / 3.0

OK, MAX_STEPS, STEP_UNDERFLOW, NONFINITE, OUTPUT_FULL, INTERRUPTED = 0, 1, 2, 3, 4, 5

# ist, the controller state that persists between calls (integrator.make_workspace):
# Jacobian valid, step of the stored factorization, Newton contraction estimate, next step
# size, stuck index (a force jump the stroke sticks at, -1: none), f0 valid, the load at
# the end of the last call (its voltage is the caller's V_prev), the stop the stroke
# rests on (-1: x = 0, +1: x = x_e, 0: free) with the net zipping force there, the step
# to start the next voltage jump with (-1: none yet) and whether the step after the last
# jump is still to come
I_JOK, I_HFACT, I_ETA, I_HN, I_STUCK, I_F0OK, I_F, I_STOP, I_GHOLD, I_HJUMP, I_AFTERJ = range(11)

# cnt (int64), one call's counters: accepted and rejected steps, f and Jacobian evaluations,
# rows recorded, trace rows, output times reached, retries locating the current stop event
N_STEPS, N_REJ, N_FEV, N_JAC, N_REC, N_TR, N_OUT, N_EVTRIES = range(8)
N_COUNTERS = 8

# ev, the bracket of a stop event being located (regula falsi, Illinois rule): the time
# past the event (-inf: none), the weights of the near and far ends' values, the last
# trial's outcome (1: past the event, 2: short of it, 0: none)
EV_T, EV_WA, EV_WB, EV_PREV = range(4)

# members of w (a tuple of 15 arrays), the vectors of one step (n each): stages, their f, Newton's residual and
# update, the error estimate, scratch, the dense output's value and slope, f at the
# Jacobian's base point, a stage's constant part
W_Z1, W_Z2, W_F0, W_F1, W_F2, W_FZ, W_RES, W_DZ, W_ERR, W_TMP, W_YTMP, W_YI, W_YDI, W_FBASE, W_BASE = range(15)

# rows of eg (NPOW each): the energy accumulators, their value before the step, the
# powers at the step's start, stage and end, and the accumulators at an output time
G_E, G_EOLD, G_P0, G_P1, G_P2, G_EINT = range(6)
G_ROWS = 6
