"""Batch unwarping of video archives and image sets on a Dask cluster (``omnidev batch``).

| module | what it holds |
|---|---|
| omnidev.batch.inputs | inputs from paths, globs and manifests; output paths |
| omnidev.batch.avrange | videos cut into frame ranges at keyframes, read per range, joined |
| omnidev.batch.tasks | the functions run on the workers |
| omnidev.batch.journal | the job manifest that makes a job resumable |
| omnidev.batch.runner | the client: planning, submission, retries, summary |

Dask (``pip install 'omnidev[batch]'``) is imported only by the runner and
the CLI, so the rest imports and tests without it. docs/batch.md is the guide.
"""
