"""The gnss_ins command-line tool and its sub-commands."""
