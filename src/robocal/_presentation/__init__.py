"""What people read: display units, the text summaries the command line prints, the HTML report
and its plots, the history page. Pure functions of result records.

May import: every folder above it (``_base`` to ``_store``).
"""
