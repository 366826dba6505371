"""Forecast room: the time and accuracy a run will reach, and the report of it.

Nothing below imports it.
"""
