"""Inputs room: IMU and GNSS samples checked, brought into the body frame and buffered.

No engine is loaded from here (a contract checks it).
"""
