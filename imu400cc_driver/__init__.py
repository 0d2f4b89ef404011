"""Crossbow IMU400CC-100 driver: protocol core, device clock, serial link, node, emulator."""
