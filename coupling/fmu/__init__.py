"""The HammerBitRock FMU: its build, the one loader, and the native front.

* :mod:`.build` -- building ``HammerBitRock.fmu``;
* :mod:`.host` -- the project's one FMU loader (fmpy);
* :mod:`.native` -- the native front's C sources and their build.
"""
