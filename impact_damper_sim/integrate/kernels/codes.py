"""Codes the exact propagator's kernels share: status codes, event kinds, sticking rules and
work counters.

:func:`.event_loop.advance` returns a status code; each event it records has a kind (in the order
of :data:`~impact_damper_sim.integrate.events.EVENT_KINDS`); its caller passes the sticking
rule; ``counters`` (``CNT_*``) count the work done by the event loop (:mod:`.event_loop`), the
event search (:mod:`.search`) and the contact handling (:mod:`.contact`). Plain integers,
constants of the compiled kernels; kept in one module that the three import, so that none of
them imports another only for its codes.
"""
from __future__ import annotations

# status codes returned by advance()
DONE = 0
CONFIG_CHANGE = 1
BUFFER_FULL = 2
NONFINITE = 3
CHATTER = 4

# event kinds
EV_IMPACT = 0
EV_STICK = 1
EV_RELEASE = 2
EV_GRAZE = 3

# sticking rules
STICK_NONE = 0
STICK_PAPER = 1
STICK_ACCUMULATION = 2

# counters
CNT_STEPS = 0          # output steps
CNT_SEARCHES = 1       # event searches (sub-intervals with impactors)
CNT_CANDIDATES = 2     # event functions that passed the filters (Taylor stage)
CNT_TAYLOR = 3         # high-order expansions of the state
CNT_EVALS = 4          # flow evaluations at arbitrary times, outside the ledger
CNT_LEDGER_PANELS = 5  # Taylor panels of the energy ledger (pieces it takes in series)
CNT_FALLBACK = 6       # event functions decided by the safe-step scan
CNT_SWITCHES = 7       # configuration switches inside the kernel
CNT_SEGMENTS = 8       # sub-intervals cut short at a Taylor segment end
CNT_QUIET = 9          # output steps certified event-free in advance (no search)
CNT_LEDGER_CLOSED = 10  # pieces of a step whose ledger is in closed form (no series)
CNT_CERTIFIED = 11     # Taylor models sent to certified_first_root (after the range bounds)
N_COUNTERS = 12
