"""Atlas storage: SQLAlchemy schema and the one engine factory (SQLite default, any URL),
build writes (``db.writes``), the content digest (``db.digest``), summaries (``db.summary``)."""

from db.engine import AtlasError, database_url, open_atlas, sqlite_path
from db.schema import APPLICATION, SCHEMA_VERSION, Base, Build, Dwell, Linkage, Meta, Segment, Shard

__all__ = [
    "APPLICATION",
    "SCHEMA_VERSION",
    "AtlasError",
    "Base",
    "Build",
    "Dwell",
    "Linkage",
    "Meta",
    "Segment",
    "Shard",
    "database_url",
    "open_atlas",
    "sqlite_path",
]
