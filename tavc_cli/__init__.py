"""tavc: a reproduction of task allocation through vacancy chains in multi-robot transportation."""

__version__ = "0.1.0"
