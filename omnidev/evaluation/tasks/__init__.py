"""Evaluation tasks: one module per task, each defining ``TASK`` (see :mod:`omnidev.evaluation`)."""
