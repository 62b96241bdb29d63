"""The store of calibrations (SQLite or PostgreSQL): records, schema, a robot's history and its
judged changes, robots of one type compared.

May import: every folder above it (``_base`` to ``_files``).
"""
