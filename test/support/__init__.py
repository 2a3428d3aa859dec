"""Helpers shared by the tests of every folder under test/ (importable as ``support.<module>``: conftest.py puts
test/ on sys.path). The pytest fixtures built on them are in test/conftest.py."""
