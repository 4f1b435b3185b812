-- An attempt may end 'released': its worker stopped and gave the cell back (not a failure,
-- not counted towards the attempt limit). SQLite cannot change a CHECK constraint in place,
-- so the table is rebuilt by SQLite's documented procedure; the store runs migrations on a
-- connection with foreign keys off and checks them afterwards (PRAGMA foreign_key_check).
CREATE TABLE attempts_new (
    id                 INTEGER PRIMARY KEY,
    cell_id            INTEGER NOT NULL REFERENCES cells(id),
    worker_id          TEXT    NOT NULL REFERENCES workers(id),
    slot               INTEGER NOT NULL,
    state              TEXT    NOT NULL CHECK (state IN ('running', 'done', 'failed', 'expired', 'cancelled', 'released')),
    resumed_from_epoch INTEGER NOT NULL DEFAULT 0,   -- 0: started fresh
    started_unix_ms    INTEGER NOT NULL,
    ended_unix_ms      INTEGER,
    error              TEXT
);
INSERT INTO attempts_new (id, cell_id, worker_id, slot, state, resumed_from_epoch, started_unix_ms, ended_unix_ms, error)
    SELECT id, cell_id, worker_id, slot, state, resumed_from_epoch, started_unix_ms, ended_unix_ms, error FROM attempts;
DROP TABLE attempts;
ALTER TABLE attempts_new RENAME TO attempts;
CREATE INDEX attempts_by_cell ON attempts(cell_id);
CREATE INDEX attempts_by_state ON attempts(state);
