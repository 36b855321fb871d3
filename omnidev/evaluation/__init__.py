"""Statistical evaluation of the methods over randomized scenes (``omnidev eval``).

A *task* runs one method on one randomized scene drawn from a seed and returns a
:class:`~omnidev.evaluation.framework.SceneResult`: the scene's classes (labels
such as resolution or codec, reported apart), ``ok`` or ``refused`` with the
method's message, named figures (errors in stated units), counts and flags.
:func:`~omnidev.evaluation.framework.evaluate` runs a task over N scenes from
seed S (scene seeds S .. S+N-1) on ``jobs`` processes with a tqdm bar, and
pools: refusals with their messages, each figure's mean / median / p95 / max
with the worst scenes' seeds, every class apart, and the task's own
acceptance checks. An unexpected exception in a scene is an ``error`` (a bug),
never a refusal.

Adding a task (e.g. ``laser``, ``mouse``): write ``omnidev/evaluation/tasks/NAME.py``
defining ``TASK = Task(name="NAME", help=..., run_scene=..., summarize=...,
options={...})``; it is found by its file name, nothing else to edit.

- ``run_scene(seed, options, outdir)`` draws its scene from ``seed`` (e.g.
  :func:`omnidev.sim.screen_scenes.draw_scene`), runs the method, measures it
  against the exact truth and returns a ``SceneResult``; with ``outdir`` (a
  folder, for ``omnidev eval TASK --scene-seed K --write DIR``) it also writes
  the scene's images and truth there for inspection.
- ``summarize(results, options)`` (optional) returns task-level figures and
  ``acceptance``: a list of ``{"name", "value", "bound", "passed"}``.
- ``options``: defaults of the task's options (``--opt KEY=VALUE``); the type of
  each default is the type of its values.
- ``headline``: the figures shown per class.

Example:
    >>> from omnidev.evaluation.framework import task_names
    >>> "screen" in task_names()
    True
"""
