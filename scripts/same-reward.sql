-- The same-reward spread of a recording (BENCHMARKS "Session 43"): for each terrain and row w1,
-- the first-seed cells whose torque penalty is under 1% of the tracking reward over training
-- (the report's ReportCell::torque_share against NEGLIGIBLE_TORQUE_SHARE). Their weights give
-- the same reward, so they are runs that differ by their seed: their scores (by w2), mean and
-- standard deviation. It picks cells, not columns: the report's sentence names a column only
-- when every cell of it is under 1% (negligible_torque_columns), so a row here may count a
-- cell whose column the report leaves out. The report's index.html prints the same rows
-- (ReportData::same_reward_rows) with their pooled SD.
--
--   sqlite3 -readonly -header -column studies/recordings/anymal/gaitsweep.sqlite < scripts/same-reward.sql
WITH share AS (
  SELECT cell_id,
         AVG(CASE WHEN name = 'reward/torques' THEN ABS(value) END)
       / AVG(CASE WHEN name = 'reward/tracking_lin_vel' THEN value END) AS share
  FROM epoch_metrics GROUP BY cell_id),
runs AS (
  SELECT c.terrain, c.w1, c.w2, s.score
  FROM scores s JOIN cells c ON c.id = s.cell_id JOIN share h ON h.cell_id = c.id
  WHERE h.share < 0.01 AND c.replicate = 0),
rows AS (
  SELECT terrain, w1, AVG(score) AS mean, COUNT(*) AS n FROM runs GROUP BY terrain, w1)
SELECT r.terrain, round(r.w1, 2) AS w1, r.n,
       (SELECT group_concat(round(x.score, 3), ' / ')
          FROM (SELECT score FROM runs x WHERE x.terrain = r.terrain AND x.w1 = r.w1 ORDER BY x.w2) x) AS scores,
       round(r.mean, 3) AS mean,
       round(sqrt((SELECT SUM((x.score - r.mean) * (x.score - r.mean)) FROM runs x
                   WHERE x.terrain = r.terrain AND x.w1 = r.w1) / (r.n - 1)), 3) AS sd
FROM rows r WHERE r.n > 1 ORDER BY r.terrain, r.w1;
