//! The coordinator's refusals, against the real binary: missing or wrong token, bad
//! spec, unknown sweep, corrupt and oversized uploads, retried results; and that nothing
//! is stored when a request is refused.

mod common;

use common::*;
use gaitsweep_core::pb::upload_checkpoint_request::Part;
use gaitsweep_core::pb::{
    self, sweep_service_client::SweepServiceClient, worker_service_client::WorkerServiceClient,
};
use sha2::Digest;
use tonic::{Code, Request};

const TOKEN: &str = "t0ken";

fn authed<T>(msg: T) -> Request<T> {
    let mut r = Request::new(msg);
    r.metadata_mut()
        .insert("authorization", format!("Bearer {TOKEN}").parse().unwrap());
    r
}

fn upload(
    lease: i64,
    sha: &str,
    size: u64,
    data: Vec<u8>,
) -> Request<tokio_stream::Iter<std::vec::IntoIter<pb::UploadCheckpointRequest>>> {
    let msgs = vec![
        pb::UploadCheckpointRequest {
            part: Some(Part::Header(pb::UploadHeader {
                lease_id: lease,
                epoch: 1,
                sha256: sha.into(),
                size,
            })),
        },
        pb::UploadCheckpointRequest {
            part: Some(Part::Chunk(pb::CheckpointChunk { data })),
        },
    ];
    authed(tokio_stream::iter(msgs))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn refusals_have_the_right_codes_and_store_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let coord = Coord::start(
        tmp.path(),
        "127.0.0.1:0",
        &["--token", TOKEN, "--max-checkpoint-mb", "1"],
    )
    .await;
    let ch = coord.channel().await;
    let mut c = SweepServiceClient::new(ch.clone());
    let mut w = WorkerServiceClient::new(ch.clone());

    // missing / wrong token
    let e = c.list_sweeps(pb::ListSweepsRequest {}).await.unwrap_err();
    assert_eq!(e.code(), Code::Unauthenticated);
    let mut wrong = Request::new(pb::ListSweepsRequest {});
    wrong
        .metadata_mut()
        .insert("authorization", "Bearer nope".parse().unwrap());
    assert_eq!(
        c.list_sweeps(wrong).await.unwrap_err().code(),
        Code::Unauthenticated
    );
    let mut health = tonic_health::pb::health_client::HealthClient::new(ch.clone());
    let e = health
        .check(tonic_health::pb::HealthCheckRequest {
            service: String::new(),
        })
        .await
        .unwrap_err();
    assert_eq!(
        e.code(),
        Code::Unauthenticated,
        "health too needs the token"
    );
    let ok = health
        .check(authed(tonic_health::pb::HealthCheckRequest {
            service: "gaitsweep.v1.SweepService".into(),
        }))
        .await
        .unwrap();
    assert_eq!(
        ok.into_inner().status,
        tonic_health::pb::health_check_response::ServingStatus::Serving as i32
    );
    let no_token_create = c
        .create_sweep(pb::CreateSweepRequest {
            spec: Some(pb::create_sweep_request::Spec::Toml(tiny_spec(
                &[2.0],
                &[-3.0],
                1,
            ))),
        })
        .await
        .unwrap_err();
    assert_eq!(no_token_create.code(), Code::Unauthenticated);

    // bad spec: every problem listed
    let bad = "robot = \"nosuchrobot\"\nterrains = [\"lava\"]\nepochs = 0\n";
    let e = c
        .create_sweep(authed(pb::CreateSweepRequest {
            spec: Some(pb::create_sweep_request::Spec::Toml(bad.into())),
        }))
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument);
    for needle in ["nosuchrobot", "lava", "epochs is 0"] {
        assert!(
            e.message().contains(needle),
            "{needle} not in {}",
            e.message()
        );
    }
    let e = c
        .create_sweep(authed(pb::CreateSweepRequest {
            spec: Some(pb::create_sweep_request::Spec::Toml("robot = [".into())),
        }))
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument);
    let db = coord.db().await;
    let sweeps: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM sweeps")
        .fetch_one(&db)
        .await
        .unwrap();
    assert_eq!(sweeps, 0, "nothing stored for refused specs");

    // unknown sweep
    assert_eq!(
        c.get_sweep(authed(pb::GetSweepRequest { sweep_id: 42 }))
            .await
            .unwrap_err()
            .code(),
        Code::NotFound
    );
    assert_eq!(
        c.list_cells(authed(pb::ListCellsRequest { sweep_id: 42 }))
            .await
            .unwrap_err()
            .code(),
        Code::NotFound
    );
    assert_eq!(
        c.cancel_sweep(authed(pb::CancelSweepRequest { sweep_id: 42 }))
            .await
            .unwrap_err()
            .code(),
        Code::NotFound
    );
    assert_eq!(
        c.get_promoted(authed(pb::GetPromotedRequest {
            sweep_id: 42,
            terrain: String::new()
        }))
        .await
        .unwrap_err()
        .code(),
        Code::NotFound
    );

    // a structured spec works too; a fake worker leases its cell
    let spec = pb::SweepSpec {
        robot: "anymal".into(),
        terrains: vec!["flat".into()],
        w1: Some(pb::Axis {
            kind: Some(pb::axis::Kind::Values(pb::Values { values: vec![2.0] })),
        }),
        w2: Some(pb::Axis {
            kind: Some(pb::axis::Kind::Range(pb::Range {
                min: -4.0,
                max: -2.0,
                count: 2,
            })),
        }),
        agents_per_cell: 2,
        epochs: 1,
        ..Default::default()
    };
    let sweep = c
        .create_sweep(authed(pb::CreateSweepRequest {
            spec: Some(pb::create_sweep_request::Spec::Structured(spec)),
        }))
        .await
        .unwrap()
        .into_inner();
    assert_eq!(sweep.cells_total, 2);
    let reg = w
        .register(authed(pb::RegisterRequest {
            hostname: "fake".into(),
            cores: 1,
            device: "cpu".into(),
            slots: 1,
            version: "test".into(),
            cpu: String::new(),
        }))
        .await
        .unwrap()
        .into_inner();
    let lease = w
        .lease(authed(pb::LeaseRequest {
            worker_id: reg.worker_id.clone(),
            slot: 0,
        }))
        .await
        .unwrap()
        .into_inner()
        .lease
        .expect("a lease");
    let unknown_worker = w
        .lease(authed(pb::LeaseRequest {
            worker_id: "w-nobody".into(),
            slot: 0,
        }))
        .await
        .unwrap_err();
    assert_eq!(unknown_worker.code(), Code::FailedPrecondition);

    // corrupt upload: bytes do not match the announced sha256
    let data = vec![7u8; 1000];
    let wrong_sha = hex::encode(sha2::Sha256::digest(b"something else"));
    let e = w
        .upload_checkpoint(upload(lease.lease_id, &wrong_sha, 1000, data.clone()))
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument, "{e:?}");
    // announced size differs from the bytes
    let sha = hex::encode(sha2::Sha256::digest(&data));
    let e = w
        .upload_checkpoint(upload(lease.lease_id, &sha, 999, data.clone()))
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument, "{e:?}");
    // oversized: announced, and sent while announcing little
    let e = w
        .upload_checkpoint(upload(lease.lease_id, &sha, 5 << 20, data.clone()))
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::ResourceExhausted, "{e:?}");
    let big = vec![1u8; (1 << 20) + 10];
    let big_sha = hex::encode(sha2::Sha256::digest(&big));
    let e = w
        .upload_checkpoint(upload(lease.lease_id, &big_sha, 100, big))
        .await
        .unwrap_err();
    assert!(
        matches!(e.code(), Code::ResourceExhausted | Code::InvalidArgument),
        "{e:?}"
    );
    // unknown lease
    let e = w
        .upload_checkpoint(upload(999, &sha, 1000, data.clone()))
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::NotFound);
    let ckpts: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM checkpoints")
        .fetch_one(&db)
        .await
        .unwrap();
    assert_eq!(ckpts, 0, "no checkpoint row for refused uploads");
    let files = walk(&coord.data.join("checkpoints")) + walk(&coord.data.join("tmp"));
    assert_eq!(files, 0, "no checkpoint file left for refused uploads");

    // a good upload, then a result reported twice is stored once
    let up = w
        .upload_checkpoint(upload(lease.lease_id, &sha, 1000, data.clone()))
        .await
        .unwrap()
        .into_inner();
    assert_eq!(up.checkpoint.unwrap().sha256, sha);
    let score = pb::GaitScore {
        score: 0.5,
        track: 0.7,
        effort: 0.1,
        tilt: 0.1,
        progress: 0.0,
        robots: 2,
        ..Default::default()
    };
    let report = pb::ReportResultRequest {
        lease_id: lease.lease_id,
        score: Some(score),
        epochs: 1,
        final_checkpoint_sha256: sha.clone(),
    };
    assert!(
        !w.report_result(authed(report.clone()))
            .await
            .unwrap()
            .into_inner()
            .duplicate
    );
    assert!(
        w.report_result(authed(report.clone()))
            .await
            .unwrap()
            .into_inner()
            .duplicate
    );
    let scores: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM scores")
        .fetch_one(&db)
        .await
        .unwrap();
    assert_eq!(scores, 1, "a retried report never duplicates a row");
    let e = w
        .report_result(authed(pb::ReportResultRequest {
            lease_id: 999,
            ..report
        }))
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::NotFound);

    // progress after the cell is done is refused; cancelling the sweep stops the rest
    let e = w
        .report_progress(authed(pb::ReportProgressRequest {
            lease_id: lease.lease_id,
            epochs: vec![],
        }))
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::FailedPrecondition);
    let cancelled = c
        .cancel_sweep(authed(pb::CancelSweepRequest {
            sweep_id: sweep.sweep_id,
        }))
        .await
        .unwrap()
        .into_inner();
    assert_eq!(cancelled.state, pb::SweepState::Cancelled as i32);
    let none = w
        .lease(authed(pb::LeaseRequest {
            worker_id: reg.worker_id,
            slot: 0,
        }))
        .await
        .unwrap()
        .into_inner();
    assert!(none.lease.is_none());

    // reflection answers generic clients (v1)
    let mut refl =
        tonic_reflection::pb::v1::server_reflection_client::ServerReflectionClient::new(ch);
    let req = tonic_reflection::pb::v1::ServerReflectionRequest {
        host: String::new(),
        message_request: Some(
            tonic_reflection::pb::v1::server_reflection_request::MessageRequest::ListServices(
                String::new(),
            ),
        ),
    };
    let mut stream = refl
        .server_reflection_info(authed(tokio_stream::iter(vec![req])))
        .await
        .unwrap()
        .into_inner();
    let msg = stream.message().await.unwrap().unwrap();
    let text = format!("{msg:?}");
    assert!(
        text.contains("gaitsweep.v1.SweepService") && text.contains("gaitsweep.v1.WorkerService"),
        "{text}"
    );
}

fn walk(dir: &std::path::Path) -> usize {
    let Ok(rd) = std::fs::read_dir(dir) else {
        return 0;
    };
    rd.flatten()
        .map(|e| {
            if e.path().is_dir() {
                walk(&e.path())
            } else {
                1
            }
        })
        .sum()
}
