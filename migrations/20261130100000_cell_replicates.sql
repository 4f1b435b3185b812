-- Replicates: a grid point (terrain, w1, w2) may be trained several times with different
-- seeds (`seeds = k` in a spec); each replicate is a cell of its own (leased, resumed and
-- scored like any cell) numbered by `replicate` from 0. Cells stored before have replicate
-- 0. The UNIQUE constraint gains the replicate, which SQLite cannot change in place: the
-- table is rebuilt as in 20261130000000_attempt_released.sql (foreign keys off, checked
-- after).
CREATE TABLE cells_new (
    id                     INTEGER PRIMARY KEY,
    sweep_id               INTEGER NOT NULL REFERENCES sweeps(id),
    terrain_index          INTEGER NOT NULL,
    terrain                TEXT    NOT NULL,
    w1_index               INTEGER NOT NULL,
    w2_index               INTEGER NOT NULL,
    w1                     REAL    NOT NULL,
    w2                     REAL    NOT NULL,     -- torque penalty weight is 10^w2
    replicate              INTEGER NOT NULL DEFAULT 0,
    seed                   INTEGER NOT NULL,
    state                  TEXT    NOT NULL CHECK (state IN ('queued', 'running', 'done', 'failed', 'cancelled')),
    attempts               INTEGER NOT NULL DEFAULT 0,
    epochs_done            INTEGER NOT NULL DEFAULT 0,
    last_error             TEXT,
    last_checkpoint_sha256 TEXT    REFERENCES checkpoints(sha256),
    last_checkpoint_epoch  INTEGER,
    UNIQUE (sweep_id, terrain_index, w1_index, w2_index, replicate)
);
INSERT INTO cells_new (id, sweep_id, terrain_index, terrain, w1_index, w2_index, w1, w2, replicate,
                       seed, state, attempts, epochs_done, last_error, last_checkpoint_sha256,
                       last_checkpoint_epoch)
    SELECT id, sweep_id, terrain_index, terrain, w1_index, w2_index, w1, w2, 0,
           seed, state, attempts, epochs_done, last_error, last_checkpoint_sha256,
           last_checkpoint_epoch FROM cells;
DROP TABLE cells;
ALTER TABLE cells_new RENAME TO cells;
CREATE INDEX cells_by_state ON cells(state, sweep_id, id);
