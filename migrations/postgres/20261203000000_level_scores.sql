-- Per-level evaluation and the score's failure modes (issue 39); the SQLite migration of
-- the same name says why.
CREATE TABLE level_scores (
    cell_id          BIGINT NOT NULL REFERENCES cells(id),
    epoch            BIGINT NOT NULL,
    level            BIGINT NOT NULL CHECK (level BETWEEN 0 AND 9),
    attempt_id       BIGINT REFERENCES attempts(id),
    score            DOUBLE PRECISION NOT NULL,
    track            DOUBLE PRECISION NOT NULL,
    effort           DOUBLE PRECISION NOT NULL,
    tilt             DOUBLE PRECISION NOT NULL,
    progress         DOUBLE PRECISION NOT NULL,
    progress_bounded DOUBLE PRECISION NOT NULL,
    fall_rate        DOUBLE PRECISION NOT NULL,
    mean_vel_error   DOUBLE PRECISION NOT NULL,
    mean_speed       DOUBLE PRECISION NOT NULL,
    overspeed        DOUBLE PRECISION NOT NULL,
    robots           BIGINT NOT NULL,
    PRIMARY KEY (cell_id, epoch, level)
);
ALTER TABLE scores ADD COLUMN progress_bounded DOUBLE PRECISION;
ALTER TABLE scores ADD COLUMN mean_speed DOUBLE PRECISION;
ALTER TABLE scores ADD COLUMN overspeed DOUBLE PRECISION;
ALTER TABLE evaluations ADD COLUMN progress_bounded DOUBLE PRECISION;
ALTER TABLE evaluations ADD COLUMN mean_speed DOUBLE PRECISION;
ALTER TABLE evaluations ADD COLUMN overspeed DOUBLE PRECISION;
-- The grid point best across a sweep's terrains (coordinator/src/across.rs) is promoted
-- with terrain '*', its score the min over terrains of its mean / that terrain's best mean,
-- and this half-width of the 95% interval of that value (NULL for other promotions).
ALTER TABLE promotions ADD COLUMN ci95 DOUBLE PRECISION;
