-- Per-level evaluation and the score's failure modes (issue 39).
--
-- A cell on rough, stairs or slopes is evaluated at several difficulty levels and scored
-- with their mean; `level_scores` keeps each level's score, one row per cell, epoch and
-- level, for the final score (epoch = scores.epochs), rung and periodic evaluations alike.
-- `scores` and `evaluations` gain the bounded progress term (each step's displacement
-- capped at its commanded distance), the mean speed and the overspeed (mean of
-- max(0, |v| - |v_cmd|)); rows written before this migration leave them NULL.
CREATE TABLE level_scores (
    cell_id          INTEGER NOT NULL REFERENCES cells(id),
    epoch            INTEGER NOT NULL,
    level            INTEGER NOT NULL CHECK (level BETWEEN 0 AND 9),
    attempt_id       INTEGER REFERENCES attempts(id),
    score            REAL    NOT NULL,
    track            REAL    NOT NULL,
    effort           REAL    NOT NULL,
    tilt             REAL    NOT NULL,
    progress         REAL    NOT NULL,
    progress_bounded REAL    NOT NULL,
    fall_rate        REAL    NOT NULL,
    mean_vel_error   REAL    NOT NULL,
    mean_speed       REAL    NOT NULL,
    overspeed        REAL    NOT NULL,
    robots           INTEGER NOT NULL,
    PRIMARY KEY (cell_id, epoch, level)
);
ALTER TABLE scores ADD COLUMN progress_bounded REAL;
ALTER TABLE scores ADD COLUMN mean_speed REAL;
ALTER TABLE scores ADD COLUMN overspeed REAL;
ALTER TABLE evaluations ADD COLUMN progress_bounded REAL;
ALTER TABLE evaluations ADD COLUMN mean_speed REAL;
ALTER TABLE evaluations ADD COLUMN overspeed REAL;
-- The grid point best across a sweep's terrains (coordinator/src/across.rs) is promoted
-- with terrain '*', its score the min over terrains of its mean / that terrain's best mean,
-- and this half-width of the 95% interval of that value (NULL for other promotions).
ALTER TABLE promotions ADD COLUMN ci95 REAL;
