"""One scene of the hammer-bit-rock model: the run, its analyses and its figure.

* :mod:`.simulate` -- one simulation request and its result;
* :mod:`.analysis` -- period-n and the largest Lyapunov exponent;
* :mod:`.plots` -- the figures of the paper's analyses;
* :mod:`.figure` -- the scene figure's data and drawing (matplotlib only);
* :mod:`.figure_worker` -- drawing a figure in a second process.
"""
