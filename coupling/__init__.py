"""hammerbit: resonance-hammer drilling model, FMU and drillstring coupling."""
