"""Controllers: flatness-based (the paper's Section 2) and model-free (Section 3).

- :mod:`flatfree.controllers.flatness`: flat outputs, the maps A and B, the singular speed;
- :mod:`flatfree.controllers.intelligent`: the ultra-local model and iP / iPI / iPD / iPID;
- :mod:`flatfree.controllers.vehicle`: the paper's model-free vehicle designs (and the
  natural-output one for your own loop, ``NaturalOutputController``);
- :mod:`flatfree.controllers.flat_output`: the flat-output one for your own loop
  (``FlatOutputController``).
"""

from flatfree.controllers.intelligent import (
    IP,
    IPD,
    IPI,
    IPID,
    IntelligentController,
    IntelligentParams,
    IntelligentStatus,
    error_dynamics_gains,
    intelligent_override,
    intelligent_reset,
    intelligent_status,
    intelligent_step,
    intelligent_step_external,
    make_state,
)

__all__ = [
    "IP",
    "IPD",
    "IPI",
    "IPID",
    "IntelligentController",
    "IntelligentParams",
    "IntelligentStatus",
    "error_dynamics_gains",
    "intelligent_override",
    "intelligent_reset",
    "intelligent_status",
    "intelligent_step",
    "intelligent_step_external",
    "make_state",
]
