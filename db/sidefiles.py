"""Whether the files beside an SQLite atlas are its own, decided before SQLite opens it.

SQLite trusts the files it finds beside a database: it rolls a hot ``-journal`` back into the
file (and truncates the file to the size the journal names) and applies a ``-wal``'s committed
frames, whichever database wrote them. Neither file names its database. So an atlas carries a
name of its own, and its writers put that name into every journal and log they write:

* the **atlas id**: a random non-zero 31-bit number in the database header's ``user_version``
  field (bytes 60–63 of page 1), written into the file itself, in rollback-journal mode,
  when the file is created (:func:`new_atlas_id`; before the switch to WAL mode, so the file
  on disk holds it, not only its log) or, for an atlas made before ids, when a build first
  writes to it in rollback mode;
* **every write transaction of a builder writes page 1** (:func:`mark_commits`: it rewrites
  ``user_version`` with its own value just before each commit), so the first transaction
  of every write-ahead log it leaves, and every rollback journal, holds a copy of page 1
  carrying the atlas id.

Before anything opens an existing atlas, :func:`check_side_files` reads the side files
(never writes them) and decides, as SQLite would apply them:

``-journal``
    not hot (missing, empty, first byte 0): SQLite ignores it. Hot: its records are parsed
    as SQLite replays them (segment headers, ``nRec``, the per-record checksum over the nonce
    and every 200th byte; replay stops at the first bad checksum). **Own** when the replayed
    records hold page 1 whose header names this atlas (the same atlas id; an atlas without an
    id: also the whole rest of page 1 — the schema — the same) with the file's page size and
    a change counter the file holds or one less. **Harmless** when nothing would be replayed
    and the journal's initial size is the file's size (then SQLite only deletes it). Anything
    else is refused: rolled back, another database's pages would overwrite the atlas's and
    the file would be truncated to the other database's size.
``-wal``
    beside a file in rollback (DELETE) mode — every complete atlas — always refused: its own
    log was folded in before the switch, and SQLite would apply any log it finds. Beside a
    WAL-mode file (a build in progress): ignored by SQLite when its header's magic number or
    checksum is wrong; refused when its page size differs; harmless when it holds no complete
    transaction (frames with the header's salts up to a commit frame); else **own** only when
    its first complete transaction holds page 1 naming this atlas (frames of one log share
    its random 64-bit salts, so the rest of the log was written by the same connection).
``-shm``
    never needs proof: it is an index of the ``-wal`` that SQLite rebuilds from the log. The
    first connection to an atlas that no process has open truncates it (SQLite's "DMS" lock)
    before reading it; while a process has it open it is that process's index of this file.

What this does not catch (docs/atlas-files.md): a log or journal of a *copy* of the same
atlas (the same id) made before the copy diverged; an atlas without an id (made before ids)
beside the log of another id-less atlas of the same schema; anyone who writes the side files
on purpose (they could as well write the atlas).
"""

from __future__ import annotations

import enum
import secrets
from dataclasses import dataclass
from pathlib import Path

__all__ = [
    "ATLAS_ID_OFFSET",
    "Ownership",
    "Verdict",
    "atlas_id",
    "journal_verdict",
    "mark_commits",
    "new_atlas_id",
    "read_page_one",
    "wal_page_size",
    "wal_verdict",
]

#: Where the atlas id lives: the database header's ``user_version`` (4 bytes, big-endian).
ATLAS_ID_OFFSET = 60
#: Magic numbers of a WAL file header (the low bit: checksums in big-endian words).
_WAL_MAGIC = (0x377F0682, 0x377F0683)
_WAL_HEADER = 32
_WAL_FRAME_HEADER = 24
_JOURNAL_MAGIC = bytes.fromhex("d9d505f920a163d7")
#: Header bytes of page 1 that no write of an atlas changes once it has its id: the page size
#: (16–17), reserved space and payload fractions (20–23), the atlas id (60–63), the
#: application id (68–71). (The schema cookie, format and text encoding change when the
#: first tables are made; counters, sizes and the free list with every write.)
_FIXED = (slice(16, 18), slice(20, 24), slice(ATLAS_ID_OFFSET, ATLAS_ID_OFFSET + 4), slice(68, 72))


class Ownership(enum.Enum):
    """What a side file is to the atlas beside it."""

    ABSENT = "absent"  #: no such file, or nothing SQLite would read from it
    HARMLESS = "harmless"  #: SQLite would read it but apply nothing to the atlas
    OWN = "own"  #: written by a connection to this very atlas
    FOREIGN = "foreign"  #: not proven its own (``Verdict.why`` says what was found)


@dataclass(frozen=True, slots=True)
class Verdict:
    """A side file's :class:`Ownership` and, when foreign, why (a clause for the message)."""

    ownership: Ownership
    why: str = ""


def new_atlas_id() -> int:
    """A random atlas id: 1 … 2³¹ − 1 (``user_version`` is a signed 32-bit integer)."""
    return secrets.randbelow(2**31 - 1) + 1


def atlas_id(page_one: bytes) -> int:
    """The atlas id in page 1 (0: none, an atlas made before ids or not yet named)."""
    return int.from_bytes(page_one[ATLAS_ID_OFFSET : ATLAS_ID_OFFSET + 4], "big") if len(page_one) >= 100 else 0


def page_size(page_one: bytes) -> int | None:
    """The page size the database header declares (None for a file too short to have one)."""
    if len(page_one) < 100:
        return None
    size = int.from_bytes(page_one[16:18], "big")
    return 65536 if size == 1 else size


def read_page_one(path: Path) -> bytes:
    """Page 1 of the database at ``path`` (its 100-byte header at least; shorter if the file is)."""
    try:
        with path.open("rb") as fh:
            head = fh.read(100)
            size = page_size(head)
            return head + fh.read(size - 100) if size and size > 100 else head
    except OSError:
        return b""


def _fixed(page: bytes, *, with_id: bool = True) -> bytes:
    """Page 1's header bytes that no atlas write changes (:data:`_FIXED`)."""
    return b"".join(page[span] for span in _FIXED if with_id or span.start != ATLAS_ID_OFFSET)


def _names_this_atlas(copy: bytes, page_one: bytes, *, id_being_set: bool = False) -> bool:
    """Whether ``copy`` (page 1 as a journal or log holds it) is page 1 of the atlas whose
    page 1 on disk is ``page_one``: the same page size and fixed header bytes and the same
    atlas id. An atlas without an id (or one whose id a build is setting: ``id_being_set``,
    for a journal's copy without one) must also have the same rest of page 1 (the schema)
    and header but for the bytes a write changes."""
    if len(copy) != len(page_one) or len(page_one) < 100:
        return False
    ours, theirs = atlas_id(page_one), atlas_id(copy)
    if theirs and theirs == ours:
        return _fixed(copy) == _fixed(page_one)
    if theirs == 0 and (ours == 0 or id_being_set):
        return (
            _fixed(copy, with_id=False) == _fixed(page_one, with_id=False)
            and copy[100:] == page_one[100:]
            and copy[40:60] == page_one[40:60]
        )  # the schema cookie, format, cache size, root, encoding
    return False


# ------------------------------------------------------------------------------ rollback journal


def journal_verdict(journal: Path, page_one: bytes, file_size: int) -> Verdict:
    """Whether the rollback journal ``journal`` belongs to the database whose page 1 is
    ``page_one`` and whose file holds ``file_size`` bytes (module docstring)."""
    try:
        with journal.open("rb") as fh:
            data = fh.read()
    except FileNotFoundError:
        return Verdict(Ownership.ABSENT)
    except OSError as exc:
        return Verdict(Ownership.FOREIGN, f"it cannot be read ({exc.strerror})")
    if not data or data[0] == 0:
        return Verdict(Ownership.ABSENT)  # not hot: SQLite leaves it alone
    size = page_size(page_one)
    if data[:8] != _JOURNAL_MAGIC or len(data) < 28 or size is None:
        return Verdict(Ownership.FOREIGN, "it is not a rollback journal SQLite would leave")
    sector = int.from_bytes(data[20:24], "big")
    journal_page = int.from_bytes(data[24:28], "big")
    initial_pages = int.from_bytes(data[16:20], "big")
    if journal_page != size:
        return Verdict(Ownership.FOREIGN, f"it holds pages of {journal_page} bytes, the atlas's are {size}")
    if sector == 0:
        sector = 4096  # SQLite then takes the VFS's sector size (4096 on Unix)
    if not 32 <= sector <= 65536 or sector & (sector - 1):
        return Verdict(Ownership.FOREIGN, "it is not a rollback journal SQLite would leave")
    replayed = list(_journal_records(data, sector, size))
    pages = file_size // size
    if not replayed:
        if initial_pages == pages:
            return Verdict(Ownership.HARMLESS)
        return Verdict(
            Ownership.FOREIGN, f"rolling it back would resize the atlas from {pages} to {initial_pages} pages"
        )
    copy = next((page for number, page in replayed if number == 1), None)
    if copy is None:
        return Verdict(Ownership.FOREIGN, "it holds no copy of the atlas's first page, so nothing shows whose it is")
    if not _names_this_atlas(copy, page_one, id_being_set=atlas_id(copy) == 0):
        return Verdict(Ownership.FOREIGN, "its copy of the first page is another database's")
    counter, ours = (int.from_bytes(p[24:28], "big") for p in (copy, page_one))
    if ours not in (counter, (counter + 1) & 0xFFFFFFFF):
        return Verdict(Ownership.FOREIGN, f"it was written at change {counter}, the atlas is at change {ours}")
    return Verdict(Ownership.OWN)


def _journal_records(data: bytes, sector: int, size: int):
    """(page number, page) of every record SQLite would replay from the journal ``data``:
    segment after segment (each a header at a sector boundary, ``nRec`` records), stopping at
    the first record whose checksum fails or that the file does not hold whole."""
    record = 4 + size + 4
    offset = 0
    while offset + 28 <= len(data) and data[offset : offset + 8] == _JOURNAL_MAGIC:
        n_rec = int.from_bytes(data[offset + 8 : offset + 12], "big")
        nonce = int.from_bytes(data[offset + 12 : offset + 16], "big")
        start = offset + sector
        if n_rec == 0xFFFFFFFF:  # written without syncs: as many as the file holds
            n_rec = (len(data) - start) // record
        for i in range(n_rec):
            at = start + i * record
            if at + record > len(data):
                return
            number = int.from_bytes(data[at : at + 4], "big")
            page = data[at + 4 : at + 4 + size]
            stored = int.from_bytes(data[at + 4 + size : at + record], "big")
            check = (nonce + sum(page[size - 200 : 0 : -200])) & 0xFFFFFFFF  # bytes size−200, size−400, … > 0
            if number == 0 or stored != check:
                return
            yield number, page
        end = start + n_rec * record
        offset = -(-end // sector) * sector  # the next segment starts at a sector boundary
        if n_rec == 0:
            return


# ------------------------------------------------------------------------------ write-ahead log


def _wal_checksum(data: bytes, big_endian: bool) -> tuple[int, int]:
    """SQLite's WAL checksum of ``data`` (a multiple of 8 bytes), as (s0, s1)."""
    order = "big" if big_endian else "little"
    s0 = s1 = 0
    for i in range(0, len(data), 8):
        s0 = (s0 + int.from_bytes(data[i : i + 4], order) + s1) & 0xFFFFFFFF
        s1 = (s1 + int.from_bytes(data[i + 4 : i + 8], order) + s0) & 0xFFFFFFFF
    return s0, s1


def _wal_header(head: bytes) -> bytes | None:
    """``head`` if it is a WAL header SQLite would use (magic number and checksum), else None."""
    if len(head) < _WAL_HEADER:
        return None
    magic = int.from_bytes(head[0:4], "big")
    if magic not in _WAL_MAGIC:
        return None
    stored = (int.from_bytes(head[24:28], "big"), int.from_bytes(head[28:32], "big"))
    return head if _wal_checksum(head[:24], big_endian=bool(magic & 1)) == stored else None


def wal_page_size(wal: Path) -> int | None:
    """The page size a ``-wal`` file declares, or None if SQLite would ignore the file (too
    short, wrong magic number or header checksum: then it holds nothing that is applied)."""
    try:
        with wal.open("rb") as fh:
            head = _wal_header(fh.read(_WAL_HEADER))
    except OSError:
        return None
    return None if head is None else int.from_bytes(head[8:12], "big")


def wal_verdict(wal: Path, page_one: bytes) -> Verdict:
    """Whether the write-ahead log ``wal`` belongs to the WAL-mode database whose page 1 is
    ``page_one`` (module docstring). Reads the frame headers and the page-1 frames of the
    first transaction only: milliseconds for a log of thousands of frames."""
    try:
        fh = wal.open("rb")
    except FileNotFoundError:
        return Verdict(Ownership.ABSENT)
    except OSError as exc:
        return Verdict(Ownership.FOREIGN, f"it cannot be read ({exc.strerror})")
    with fh:
        head = _wal_header(fh.read(_WAL_HEADER))
        if head is None:
            return Verdict(Ownership.ABSENT)  # SQLite ignores a log with a bad header
        size = int.from_bytes(head[8:12], "big")
        ours = page_size(page_one)
        if size != ours:
            return Verdict(Ownership.FOREIGN, f"another database's: page size {size}, the atlas has {ours}")
        salts = head[16:24]
        copies: list[bytes] = []
        offset = _WAL_HEADER
        while True:
            fh.seek(offset)
            frame = fh.read(_WAL_FRAME_HEADER)
            if len(frame) < _WAL_FRAME_HEADER or frame[8:16] != salts:
                return Verdict(Ownership.HARMLESS)  # no complete transaction: nothing is applied
            if int.from_bytes(frame[0:4], "big") == 1:
                copies.append(fh.read(size))
            offset += _WAL_FRAME_HEADER + size
            if int.from_bytes(frame[4:8], "big"):  # a commit frame ends the first transaction
                break
    if any(_names_this_atlas(copy, page_one) for copy in copies):
        return Verdict(Ownership.OWN)
    if not copies:
        return Verdict(
            Ownership.FOREIGN,
            "its first transaction holds no copy of the atlas's first page, so nothing shows whose it is",
        )
    return Verdict(Ownership.FOREIGN, "another database's: its copy of the first page is not the atlas's")


# ------------------------------------------------------------------------------ the writers' part


def mark_commits(engine) -> None:  # noqa: ANN001 - an SQLAlchemy Engine (not imported here)
    """Make every write transaction of ``engine`` (SQLite) write page 1: ``user_version`` is
    rewritten with its own value just before each commit of a transaction that changed
    something, so a log or journal this engine leaves names its atlas (module docstring).
    A transaction that only read stays a read."""
    from sqlalchemy import event

    @event.listens_for(engine, "commit")
    def _name_the_log(conn) -> None:  # noqa: ANN001 - SQLAlchemy Connection
        raw = conn.connection.dbapi_connection
        if getattr(raw, "in_transaction", False):
            value = int(raw.execute("PRAGMA user_version").fetchone()[0])
            raw.execute(f"PRAGMA user_version={value}")
