"""hammerbit.ssp: the drilling system as an SSP 1.0 package (``drilling.ssp``).

:mod:`~hammerbit.ssp.document` writes and reads ``SystemStructure.ssd``;
:mod:`~hammerbit.ssp.package` builds the package (both FMUs, their
connections and parameter values, a default experiment and libcosim's
step-size annotation); :mod:`~hammerbit.ssp.run` runs it with the
project's master (``hammerbit cosim --ssp``).
"""
