"""The stages of an alignment: coarse, the self-check, handover, fine and what watches it
(convergence, consistency, the slow-error monitor).
"""
