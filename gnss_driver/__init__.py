"""NMEA 0183 GNSS driver: Leica RTK rover, Thales/Ashtech ADU5, generic receivers."""
