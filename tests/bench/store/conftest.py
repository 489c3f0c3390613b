"""The lab-store tests use the real services of tests/services.py (root conftest)."""
