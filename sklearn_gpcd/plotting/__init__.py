"""Plots of the monitoring signal (matplotlib is imported only when plotting)."""

from .monitoring import plot_monitoring

__all__ = ["plot_monitoring"]
