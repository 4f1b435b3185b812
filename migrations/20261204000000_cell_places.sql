-- An evolutionary search's cells get columns of their own (issue 41): `generation` and
-- `candidate`. Until now a CMA-ES or genetic sweep stored a candidate's generation in
-- `w1_index` and its number in `w2_index`, which every reader had to know. A cell is now
-- either a grid point (w1_index and w2_index set, generation and candidate NULL) or a
-- candidate (the other way round); the CHECK says so. Existing candidates (sweeps whose
-- spec's search method is cmaes or genetic) move to the new columns. w1_index and
-- w2_index lose NOT NULL, which SQLite cannot change in place: the table is rebuilt as in
-- 20261130200000_search.sql (foreign keys off, checked after).
CREATE TABLE cells_new (
    id                     INTEGER PRIMARY KEY,
    sweep_id               INTEGER NOT NULL REFERENCES sweeps(id),
    terrain_index          INTEGER NOT NULL,
    terrain                TEXT    NOT NULL,
    w1_index               INTEGER,              -- a grid point's row
    w2_index               INTEGER,              -- a grid point's column
    generation             INTEGER,              -- a candidate's generation
    candidate              INTEGER,              -- a candidate's number in its generation
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
    CHECK ((w1_index IS NULL) = (w2_index IS NULL)
           AND (generation IS NULL) = (candidate IS NULL)
           AND (w1_index IS NULL) <> (generation IS NULL)),
    UNIQUE (sweep_id, terrain_index, w1_index, w2_index, replicate),
    UNIQUE (sweep_id, terrain_index, generation, candidate, replicate)
);
INSERT INTO cells_new (id, sweep_id, terrain_index, terrain, w1_index, w2_index, generation,
                       candidate, w1, w2, replicate, seed, state, attempts, epochs_done,
                       target_epochs, last_error, last_checkpoint_sha256, last_checkpoint_epoch)
    SELECT c.id, c.sweep_id, c.terrain_index, c.terrain,
           CASE WHEN e.evolutionary THEN NULL ELSE c.w1_index END,
           CASE WHEN e.evolutionary THEN NULL ELSE c.w2_index END,
           CASE WHEN e.evolutionary THEN c.w1_index END,
           CASE WHEN e.evolutionary THEN c.w2_index END,
           c.w1, c.w2, c.replicate, c.seed, c.state, c.attempts, c.epochs_done,
           c.target_epochs, c.last_error, c.last_checkpoint_sha256, c.last_checkpoint_epoch
    FROM cells c
    JOIN (SELECT id, coalesce(json_extract(spec_json, '$.search.method') IN ('cmaes', 'genetic'), 0)
                 AS evolutionary FROM sweeps) e ON e.id = c.sweep_id;
DROP TABLE cells;
ALTER TABLE cells_new RENAME TO cells;
CREATE INDEX cells_by_state ON cells(state, sweep_id, id);
