"""Figures and tables that commands print or save."""
