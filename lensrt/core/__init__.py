"""The bottom floor: small pieces every stage uses and that import nothing else of lensrt.

Files:

- ``lazy``  lazy package faces: a package's public names imported on first use
- ``budget``  memory estimates and caps checked before a job allocates (``--max-memory``, ``--max-rays``)
- ``keep``  results kept per key in a process (a bounded dict in front of a computation)
- ``telemetry``  kernel launches, host<->device copies and seconds of a piece of work
- ``compile_ahead``  Warp modules compiled before their first launch, several at once, in background threads
"""
