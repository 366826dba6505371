"""Stages room: coarse, the self-check, handover, fine, and what watches the fine stage.

The watchers are convergence, consistency, the slow-error monitor and the course heading.
"""
