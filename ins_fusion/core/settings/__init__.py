"""The engine's parameters (one table) and its typed configuration."""
