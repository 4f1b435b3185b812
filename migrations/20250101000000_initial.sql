-- gaitsweep coordinator schema, version 1.
-- Times are unix milliseconds; hashes are lowercase hex sha256.

-- A sweep: one spec, one grid per terrain.
CREATE TABLE sweeps (
    id               INTEGER PRIMARY KEY,
    name             TEXT    NOT NULL,
    robot            TEXT    NOT NULL,
    spec_json        TEXT    NOT NULL,           -- the resolved spec (every default filled in)
    state            TEXT    NOT NULL CHECK (state IN ('running', 'done', 'cancelled')),
    created_unix_ms  INTEGER NOT NULL,
    finished_unix_ms INTEGER
);

-- Content-addressed checkpoint files under DATA_DIR/checkpoints/ab/abcdef....safetensors.
CREATE TABLE checkpoints (
    sha256          TEXT    PRIMARY KEY,
    size            INTEGER NOT NULL,
    path            TEXT    NOT NULL,            -- relative to the data dir
    created_unix_ms INTEGER NOT NULL
);

-- One (terrain, w1, w2) cell of a sweep's grid.
CREATE TABLE cells (
    id                     INTEGER PRIMARY KEY,
    sweep_id               INTEGER NOT NULL REFERENCES sweeps(id),
    terrain_index          INTEGER NOT NULL,
    terrain                TEXT    NOT NULL,
    w1_index               INTEGER NOT NULL,
    w2_index               INTEGER NOT NULL,
    w1                     REAL    NOT NULL,
    w2                     REAL    NOT NULL,     -- torque penalty weight is 10^w2
    seed                   INTEGER NOT NULL,
    state                  TEXT    NOT NULL CHECK (state IN ('queued', 'running', 'done', 'failed', 'cancelled')),
    attempts               INTEGER NOT NULL DEFAULT 0,
    epochs_done            INTEGER NOT NULL DEFAULT 0,
    last_error             TEXT,
    last_checkpoint_sha256 TEXT    REFERENCES checkpoints(sha256),
    last_checkpoint_epoch  INTEGER,
    UNIQUE (sweep_id, terrain_index, w1_index, w2_index)
);
CREATE INDEX cells_by_state ON cells(state, sweep_id, id);

-- Worker processes that registered.
CREATE TABLE workers (
    id                 TEXT    PRIMARY KEY,
    hostname           TEXT    NOT NULL,
    cores              INTEGER NOT NULL,
    device             TEXT    NOT NULL,
    slots              INTEGER NOT NULL,
    version            TEXT    NOT NULL,
    registered_unix_ms INTEGER NOT NULL,
    last_seen_unix_ms  INTEGER NOT NULL
);

-- One lease of a cell to a worker slot (an attempt). attempts.id is the lease id.
CREATE TABLE attempts (
    id                 INTEGER PRIMARY KEY,
    cell_id            INTEGER NOT NULL REFERENCES cells(id),
    worker_id          TEXT    NOT NULL REFERENCES workers(id),
    slot               INTEGER NOT NULL,
    state              TEXT    NOT NULL CHECK (state IN ('running', 'done', 'failed', 'expired', 'cancelled')),
    resumed_from_epoch INTEGER NOT NULL DEFAULT 0,   -- 0: started fresh
    started_unix_ms    INTEGER NOT NULL,
    ended_unix_ms      INTEGER,
    error              TEXT
);
CREATE INDEX attempts_by_cell ON attempts(cell_id);
CREATE INDEX attempts_by_state ON attempts(state);

-- Training metrics, one row per cell, epoch and metric name (a retried report replaces).
CREATE TABLE epoch_metrics (
    cell_id    INTEGER NOT NULL REFERENCES cells(id),
    epoch      INTEGER NOT NULL,
    name       TEXT    NOT NULL,
    value      REAL    NOT NULL,
    attempt_id INTEGER NOT NULL REFERENCES attempts(id),
    PRIMARY KEY (cell_id, epoch, name)
) WITHOUT ROWID;

-- Checkpoints a cell uploaded, by epoch.
CREATE TABLE cell_checkpoints (
    cell_id    INTEGER NOT NULL REFERENCES cells(id),
    epoch      INTEGER NOT NULL,
    sha256     TEXT    NOT NULL REFERENCES checkpoints(sha256),
    attempt_id INTEGER NOT NULL REFERENCES attempts(id),
    unix_ms    INTEGER NOT NULL,
    PRIMARY KEY (cell_id, epoch)
);

-- The gait score of a finished cell, every component (at most one row per cell).
CREATE TABLE scores (
    cell_id                 INTEGER PRIMARY KEY REFERENCES cells(id),
    attempt_id              INTEGER NOT NULL REFERENCES attempts(id),
    score                   REAL    NOT NULL,
    track                   REAL    NOT NULL,
    effort                  REAL    NOT NULL,
    tilt                    REAL    NOT NULL,
    progress                REAL    NOT NULL,
    fall_rate               REAL    NOT NULL,
    mean_vel_error          REAL    NOT NULL,
    mean_abs_torque         REAL    NOT NULL,
    cost_of_transport       REAL    NOT NULL,
    robots                  INTEGER NOT NULL,
    epochs                  INTEGER NOT NULL,
    final_checkpoint_sha256 TEXT    REFERENCES checkpoints(sha256),
    reported_unix_ms        INTEGER NOT NULL
);

-- Promotion history: each time a new best cell of a sweep (terrain '' = all terrains).
CREATE TABLE promotions (
    id               INTEGER PRIMARY KEY,
    sweep_id         INTEGER NOT NULL REFERENCES sweeps(id),
    terrain          TEXT    NOT NULL DEFAULT '',
    cell_id          INTEGER NOT NULL REFERENCES cells(id),
    score            REAL    NOT NULL,
    promoted_unix_ms INTEGER NOT NULL
);
CREATE INDEX promotions_by_sweep ON promotions(sweep_id, terrain, id);
