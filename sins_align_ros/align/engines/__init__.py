"""The fine-alignment engines (stationary, aided, moving, robust, navigation), their factory and
the models they share.
"""
