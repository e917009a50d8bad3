"""Atlas storage: SQLAlchemy schema and the one engine factory (SQLite default, any URL)."""

from db.engine import AtlasError, database_url, open_atlas
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
]
