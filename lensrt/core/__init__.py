"""The bottom floor: small pieces every stage uses and that import nothing else of lensrt.

Files:

- ``lazy``  lazy package faces: a package's public names imported on first use
- ``budget``  memory estimates and caps checked before a job allocates (``--max-memory``, ``--max-rays``)
"""
