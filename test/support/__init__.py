"""What tests and benches share: simulated bags and drives, ROS harnesses, message builders and
the repository's paths. Importable as ``support`` from every test module (test/conftest.py puts
test/ on the path) and from bench/ (which adds test/ itself)."""
