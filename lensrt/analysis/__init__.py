"""Stage 4: analyses over traced rays and pupil functions (pure functions, numpy on the host)."""
