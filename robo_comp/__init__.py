"""robo_comp: a framework for multi-robot search-and-rescue competitions."""
__version__ = "0.1.0"
