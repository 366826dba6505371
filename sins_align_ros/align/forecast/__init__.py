"""What a run is expected to reach before it runs, and the report of it.

expectation (the forecast of a pipeline), variance (the arithmetic on its variance curves),
report (the status record); nothing below imports this room.
"""
