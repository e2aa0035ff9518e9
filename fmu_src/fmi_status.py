"""FMI 2.0 status codes, as the HammerBitRock slave records them in ``last_status``."""

__all__ = ["OK", "WARNING", "DISCARD", "ERROR"]

#: fmi2OK, fmi2Warning, fmi2Discard, fmi2Error
OK, WARNING, DISCARD, ERROR = 0, 1, 2, 3
