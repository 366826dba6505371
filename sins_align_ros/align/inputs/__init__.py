"""Input handling: IMU and GNSS samples checked, converted to the body frame and buffered; no
engine is loaded from here.
"""
