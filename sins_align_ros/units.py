"""Units: the one place that converts datasheet and human units to SI and radians.

Inside the package every quantity is SI and radians; multiply a value in the unit
named here by the constant to get SI (``5.0 * DPH`` is 5 deg/h in rad/s), divide to
go back. Frame and Euler conventions live in :mod:`sins_align_ros.nav.frames`.

Import them from here: no other module re-exports them.
"""
import math

#: standard gravity, m/s^2 (the micro-g of datasheets refers to it)
G0 = 9.80665
#: degree, rad
DEG = math.pi / 180.0
#: arc minute, rad
ARCMIN = DEG / 60.0
#: arc second, rad
ARCSEC = DEG / 3600.0
#: degree per hour, rad/s (gyro bias)
DPH = DEG / 3600.0
#: degree per square-root hour, rad/sqrt(s) (gyro angle random walk)
DPSH = DEG / 60.0
#: micro-g, m/s^2 (accelerometer bias); micro-g/sqrt(Hz) is UG in m/s^2/sqrt(Hz)
UG = 1e-6 * G0
#: knot, m/s
KNOT = 1852.0 / 3600.0
