"""pythonfmu variable types that also write what pythonfmu leaves out of modelDescription.xml (unit, range, nominal)."""
from pythonfmu import Boolean, Integer, Real

__all__ = ["RealVar", "KIND", "KIND_NAME"]


class RealVar(Real):
    """pythonfmu ``Real`` that also writes ``unit``, ``min``, ``max`` and ``nominal``."""

    def __init__(self, name, unit=None, *, min=None, max=None, nominal=None, **kwargs):
        super().__init__(name, **kwargs)
        self.extra = {"unit": unit, "min": min, "max": max, "nominal": nominal}

    def to_xml(self):
        node = super().to_xml()
        real = node.find("Real")
        if self.start is not None:
            # pythonfmu writes 16 significant digits, which do not always read back as the value
            # (1.4739737117746359 -> 1.473973711774636): repr does
            real.set("start", repr(float(self.start)))
        for key, value in self.extra.items():
            if value is not None:
                real.set(key, value if isinstance(value, str) else repr(float(value)))
        return node


#: the FMI type of each variable class
KIND = {Real: Real, RealVar: Real, Integer: Integer, Boolean: Boolean}
#: the FMI type names (for messages)
KIND_NAME = {Real: "Real", Integer: "Integer", Boolean: "Boolean"}
