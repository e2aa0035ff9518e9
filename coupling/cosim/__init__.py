"""Co-simulation of the drillstring with the hammer FMU.

* :mod:`.config` -- options and results of a run;
* :mod:`.master` -- the master loop and the hammer side;
* :mod:`.string_side` -- the string and interface spring, stepped exactly;
* :mod:`.exchange` -- the per-step exchange and extrapolation;
* :mod:`.error` -- step resolution and the coupling-error estimate;
* :mod:`.reference` -- the monolithic reference.
"""
