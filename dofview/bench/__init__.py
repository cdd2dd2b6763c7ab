"""Measuring dofview: the speed-against-error benchmark, performance at scale, synthetic scenes,
image metrics and frame timing."""
