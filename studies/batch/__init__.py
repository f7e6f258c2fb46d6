"""Scale-out (issue 31): many records or many boards as one Dask run.

* :mod:`studies.batch.inputs` — a folder or glob of records becomes tasks (a file one task, a subfolder a named group);
* :mod:`studies.batch.runner` — the tasks on a scheduler (local processes, ``tcp://host:port`` or ``synchronous``):
  inputs scattered once, workers warmed once, results ordered by task key, lost workers' tasks rerun;
* :mod:`studies.batch.summary` — one table (CSV, units in the column names, and HTML) over all tasks;
* :mod:`studies.batch.fleet` — the fleet table of ``shm health --fleet`` ranked by forecast first FAULT.
"""

from studies.batch.inputs import BatchTask, expand_inputs, is_batch_input
from studies.batch.runner import BatchOutcome, TaskResult, run_tasks

__all__ = ["BatchOutcome", "BatchTask", "TaskResult", "expand_inputs", "is_batch_input", "run_tasks"]
