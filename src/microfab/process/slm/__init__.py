"""SLM scan timing on the galvo twin of seed 003 part 2.

RTC vector timing (`microfab.process.slm.timing`), lattice layers
(`microfab.process.slm.lattice`), exact propagation of the axis model over vectors
(`microfab.process.slm.propagate`) and the scan-time estimates
(`microfab.process.slm.estimate`).
"""
