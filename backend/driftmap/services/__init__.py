"""Use cases over storage: what the CLI, the API and the jobs all call.

Services take a SQLAlchemy session and a blob store (passed in, never created here) and do not
commit: the caller commits at its request or job boundary.
"""
