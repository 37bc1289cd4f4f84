"""The session store: one SQLite file per study that loses no committed answer.

Durability
----------
The database runs in WAL mode with ``synchronous=FULL``: every commit is fsynced before it returns, so a
response committed before the next trial starts survives SIGKILL and power loss. The planned trials of a
participant are written in one transaction before the first trial is shown; each response is its own
transaction, and ``responses`` has the primary key ``(participant, idx)``, so a response can never be recorded
twice. Errors (full disk, locked or foreign file) roll the transaction back and raise :class:`StoreError`, a
one-line ``ValueError``; nothing already recorded is altered.

Tables
------
``study``          key/value: store format, protocol name, version, content hash and JSON, creation time
``participants``   pseudonymous id, counterbalancing index, seed, schedule hash, enrolment time
``sessions``       id ``<participant>-s<n>``, protocol hash, software versions, display and monitor settings,
                   measured refresh rate, keyboard backend, seed, start/end (UTC), status
                   (``running``, ``completed``, ``ended`` (Escape -> end), ``interrupted`` (found running at
                   resume)), resumed-from session
``planned_trials`` the schedule: kind (trial, practice, catch, reference), scene, block, family, conditions in
                   display order (JSON), expected answer of catch trials, break flag
``responses``      one row per answered trial: raw answers (JSON), the derived chosen/chosen_2/response, RT
                   from stimulus onset, onset time, dropped frames, switches, gaze flag, catch correctness
``adaptive``       one row per trial of an adaptive design, written with its response: the procedure
                   (``VaFR@temple``), the varied parameter, the level shown, whether the answer was correct
                   (detected), the procedure's running estimate and state (JSON) after it; ``skipped``: the
                   procedure had stopped early, nothing was shown (created by the first adaptive trial)
``events``         pause, resume, end, break and error events per session; ``scenes`` (live sessions, written
                   with the session): the protocol folder and each scene's content hash, for ``replay``
                   ``fps_check`` (live sessions in a window): the frame-rate check before the first trial
                   (:meth:`Store.fps_check`); ``refused``: the check stopped the session (status ``refused``)

Exports
-------
:func:`read_trials` gives the tidy trial log (:data:`data_schema.trial_log.ALL_COLUMNS`, one row per answered
trial; references are not trials); :func:`export_csv`, :func:`export_parquet` and :func:`export_pwcmp` write it
(pwcmp: ``observer, session, scene, condition_1, condition_2, selection`` with ``selection`` 1 when
``condition_1`` was chosen and 2 when ``condition_2`` was; the trials of the families that declare the layout,
:attr:`data_schema.families.base.TrialFamily.export_columns`); :func:`export_frames` writes the frame rows.

Parts
-----
A subpackage, so that ``from data_schema.store import Store, open_store, read_trials, ...`` keeps working while
each concept has its own module (one direction of imports, no cycles):

``tables``          the schema, row checksums and checked row writes, :class:`PlannedRow`, :class:`AdaptiveRow`,
                    :class:`StoreError`
``identity``        the database's marker and format (its header), the identity of the process running a session
``integrity``       damaged files refused (:func:`verify`), frame rows checked (:func:`check_frame`)
``tidy``            the tidy log's rows (the family's columns asked of the family)
``session``         the session store, :class:`Store`
``opening``         the open modes: :func:`open_store` (``read``, ``write``, ``create``), :func:`remove_database`
``readers``         :func:`read_trials`, :func:`read_analysis_plan` (what the analysis reads)
``csv_export``, ``parquet_export``, ``pwcmp_export``, ``frames_export``: one exporter per format
"""

from __future__ import annotations

from .csv_export import export_csv, tidy_csv_text
from .frames_export import FRAMES_BLOCK_ROWS, FRAMES_ROW_GROUP_ROWS, export_frames
from .identity import process_identity, process_state
from .integrity import FRAME_PIXELS, FRAME_SCENE, FRAME_TIME_S, check_frame, damage_is_refused, verify
from .opening import open_store, remove_database
from .parquet_export import export_parquet
from .pwcmp_export import export_pwcmp
from .readers import read_analysis_plan, read_trials
from .session import Store
from .tables import (
    ADAPTIVE_SCHEMA, APPLICATION_ID, COLUMNS, OPTIONAL_TABLES, PRIMARY_KEYS, SCHEMA, SQLITE_MAGIC, STORE_FORMAT,
    WAL_AUTOCHECKPOINT_PAGES, AdaptiveRow, PlannedRow, StoreError, row_crc, utc_now)
from .tidy import adaptive_columns, tidy_frame, tidy_row

__all__ = [
    "ADAPTIVE_SCHEMA", "APPLICATION_ID", "COLUMNS", "FRAMES_BLOCK_ROWS", "FRAMES_ROW_GROUP_ROWS", "FRAME_PIXELS",
    "FRAME_SCENE", "FRAME_TIME_S", "OPTIONAL_TABLES", "PRIMARY_KEYS", "SCHEMA", "SQLITE_MAGIC", "STORE_FORMAT",
    "WAL_AUTOCHECKPOINT_PAGES", "AdaptiveRow", "PlannedRow", "Store", "StoreError", "adaptive_columns",
    "check_frame", "damage_is_refused", "export_csv", "export_frames", "export_parquet", "export_pwcmp",
    "open_store", "process_identity", "process_state", "read_analysis_plan", "read_trials", "remove_database",
    "row_crc", "tidy_csv_text", "tidy_frame", "tidy_row", "utc_now", "verify"]
