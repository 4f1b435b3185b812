-- The CPU model a worker runs on (session 34): the same cell and seed trained on two CPUs
-- ended in different gaits, and a recording spans machines, so which CPU trained each
-- attempt is stored with it (attempts.worker_id -> workers.cpu). Empty for workers that
-- registered before, or that do not say.
ALTER TABLE workers ADD COLUMN cpu TEXT NOT NULL DEFAULT '';
