"""The bottom floor: small pieces every stage uses and that import nothing else of lensrt.

Files:

- ``lazy``  lazy package faces: a package's public names imported on first use
- ``budget``  memory estimates and caps checked before a job allocates (``--max-memory``, ``--max-rays``)
- ``telemetry``  kernel launches, copies, wall and kernel seconds of a job
- ``compile_ahead``  Warp modules compiled before their first launch, several at once, in background threads
"""
