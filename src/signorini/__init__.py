"""signorini: dynamic Signorini contact with the mass redistribution method."""

__version__ = "0.1.0"
