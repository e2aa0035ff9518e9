"""Co-simulation of the drillstring with the hammer FMU.

* :mod:`.config` -- options and results of a run;
* :mod:`.master` -- the master loop (:func:`~.master.cosimulate`);
* :mod:`.lane` -- one lane: a hammer side, a string state, their exchange histories;
* :mod:`.hammer_interface` -- what a hammer side provides, the layout of its outputs;
* :mod:`.hammer_fmu`, :mod:`.hammer_inprocess` -- the FMU hammer and the in-process hammer;
* :mod:`.hammers` -- the choice of a run's hammer side;
* :mod:`.harmonic` -- the harmonic force computed by the master;
* :mod:`.string_side` -- the string and interface spring, stepped exactly;
* :mod:`.exchange` -- the per-step exchange and extrapolation;
* :mod:`.stability` -- the coupling-stability watch;
* :mod:`.recorder` -- the recorded series;
* :mod:`.error` -- step resolution and the coupling-error estimate;
* :mod:`.reference` -- the monolithic reference;
* :mod:`.linear_modes` -- the linear modes of the coupled system.
"""
