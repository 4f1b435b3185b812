-- Search strategies (successive halving) and intermediate evaluations.
--
-- cells: two more states, 'paused' (reached a rung, waits for its decision) and 'stopped'
-- (successive halving stopped it at a rung), and `target_epochs`, the epochs a cell trains
-- to before its next decision (the spec's epochs for a grid; cells stored before read
-- so). The CHECK constraint changes, so the table is rebuilt as in
-- 20261130100000_cell_replicates.sql.
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
    state                  TEXT    NOT NULL CHECK (state IN ('queued', 'running', 'done', 'failed', 'cancelled', 'paused', 'stopped')),
    attempts               INTEGER NOT NULL DEFAULT 0,
    epochs_done            INTEGER NOT NULL DEFAULT 0,
    target_epochs          INTEGER NOT NULL,
    last_error             TEXT,
    last_checkpoint_sha256 TEXT    REFERENCES checkpoints(sha256),
    last_checkpoint_epoch  INTEGER,
    UNIQUE (sweep_id, terrain_index, w1_index, w2_index, replicate)
);
INSERT INTO cells_new (id, sweep_id, terrain_index, terrain, w1_index, w2_index, w1, w2, replicate,
                       seed, state, attempts, epochs_done, target_epochs, last_error,
                       last_checkpoint_sha256, last_checkpoint_epoch)
    SELECT c.id, c.sweep_id, c.terrain_index, c.terrain, c.w1_index, c.w2_index, c.w1, c.w2,
           c.replicate, c.seed, c.state, c.attempts, c.epochs_done,
           json_extract(s.spec_json, '$.epochs'), c.last_error, c.last_checkpoint_sha256,
           c.last_checkpoint_epoch
    FROM cells c JOIN sweeps s ON s.id = c.sweep_id;
DROP TABLE cells;
ALTER TABLE cells_new RENAME TO cells;
CREATE INDEX cells_by_state ON cells(state, sweep_id, id);

-- Every evaluation of a cell's deterministic policy before its final score: at a rung of
-- successive halving (kind 'rung') or every `eval.every` epochs (kind 'periodic'). One
-- row per cell and epoch.
CREATE TABLE evaluations (
    cell_id          INTEGER NOT NULL REFERENCES cells(id),
    epoch            INTEGER NOT NULL,
    kind             TEXT    NOT NULL CHECK (kind IN ('rung', 'periodic')),
    attempt_id       INTEGER REFERENCES attempts(id),
    score            REAL    NOT NULL,
    track            REAL,
    effort           REAL,
    tilt             REAL,
    progress         REAL,
    fall_rate        REAL,
    mean_vel_error   REAL,
    robots           INTEGER,
    reported_unix_ms INTEGER NOT NULL,
    PRIMARY KEY (cell_id, epoch)
);

-- Successive halving's decisions: one per cell and rung (the key makes a second decision
-- on the same rung impossible).
CREATE TABLE rung_decisions (
    cell_id         INTEGER NOT NULL REFERENCES cells(id),
    rung            INTEGER NOT NULL,
    epoch           INTEGER NOT NULL,
    score           REAL    NOT NULL,
    decision        TEXT    NOT NULL CHECK (decision IN ('continue', 'stop')),
    decided_unix_ms INTEGER NOT NULL,
    PRIMARY KEY (cell_id, rung)
);
