"""The hammer-frequency avoidance check of the axial string modes.

* :mod:`.frequency` -- the check itself;
* :mod:`.results` -- its configuration and results;
* :mod:`.plots` -- its figures.
"""
