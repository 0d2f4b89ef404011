"""Pieces both drivers share: clock synchronisation, the reconnecting serial link, pty devices."""
