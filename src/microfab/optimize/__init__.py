"""Reference optimisation on identified models (seed 002 §IV, issue 18).

Two stages, as the seed's Fig. 4:

* `stage1` (eqs. 8-12): a minimum-time trajectory of the *linear* model (eq. 6) along the
  contour within the tolerance, on N points equally spaced in ``s`` with variable time
  steps; CasADi + IPOPT.
* `stage2` (eqs. 13-14): the timing fixed, the 400 Hz input refined with the per-axis
  networks (eq. 7) by Gauss-Newton, the network Jacobians from PyTorch.

Around them: `problem` (the contour, tolerance and bounds), `metrics` (eqs. 16-18 by
exact foot-point projection), `baseline` (eq. 15 and a stretched time-optimal command),
`command` (the 400 Hz input as a 10 kHz command within Table I).

CasADi (extra ``optimize``) and PyTorch (extra ``ann``) are imported where used.
"""
