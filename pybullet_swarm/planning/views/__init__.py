"""What each task kind shows its planners: one module per task kind.

The core types every task shares are in ``planning.base`` (``Observation`` generic in what an agent
sees, ``TaskInfo``, ``TaskView``, ``WorldView``). What only one task kind has, its own types, lives
here, one module per kind, below both the task runtimes (``tasks/``) that fill them and the planners
that read them: a new task kind adds a module, it does not edit the shared types.
"""
