"""Engines room: the fine-alignment engines, their factory and the parts they share.

The families are stationary (seed 002) and the GNSS-aided moving (seed 000), robust
(seed 004) and navigation (seeds 001/003), built on the aided driver.
"""
