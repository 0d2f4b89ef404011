"""Offline replay of bags through the fusion core (``gnss_ins replay``), in pure pieces:
inputs from a bag, outage injection, the engine run, metrics against a reference, the report,
plots, the fused output bag and parameter sweeps. No rclpy."""
