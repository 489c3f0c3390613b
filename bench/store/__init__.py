"""Where runs and constants live: the folder store (SQLite beside the run folders, the
default) and the lab catalog (PostgreSQL index + Parquet in a folder or an S3 bucket)."""
