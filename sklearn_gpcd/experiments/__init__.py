"""The paper's experiments end to end (``gpcd reproduce``)."""

from .paper import PaperConfig, reproduce, split_nmse

__all__ = ["PaperConfig", "reproduce", "split_nmse"]
