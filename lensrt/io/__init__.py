"""Stage 7 outputs: tables, JSON, EXR, PNG, plots and reports."""
