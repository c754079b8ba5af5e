"""The numba kernels of a move's fast path (``stealth_sim.compiled_move`` drives them): the
reference's operations, loop for loop, on float64 arrays laid out by :mod:`.layout`."""
