"""What a run is expected to reach before it runs (expectation) and the report of it; nothing
below imports this room.
"""
