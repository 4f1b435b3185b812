-- An evolutionary search's cells get columns of their own (issue 41); the SQLite
-- migration of the same name says why.
ALTER TABLE cells ALTER COLUMN w1_index DROP NOT NULL;
ALTER TABLE cells ALTER COLUMN w2_index DROP NOT NULL;
ALTER TABLE cells ADD COLUMN generation BIGINT;
ALTER TABLE cells ADD COLUMN candidate BIGINT;
UPDATE cells c SET generation = c.w1_index, candidate = c.w2_index, w1_index = NULL,
                   w2_index = NULL
    FROM sweeps s
    WHERE s.id = c.sweep_id AND (s.spec_json::jsonb -> 'search' ->> 'method') IN ('cmaes', 'genetic');
ALTER TABLE cells ADD CONSTRAINT cells_one_place CHECK (
    (w1_index IS NULL) = (w2_index IS NULL)
    AND (generation IS NULL) = (candidate IS NULL)
    AND (w1_index IS NULL) <> (generation IS NULL));
ALTER TABLE cells ADD CONSTRAINT cells_one_candidate
    UNIQUE (sweep_id, terrain_index, generation, candidate, replicate);
