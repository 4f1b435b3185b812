//! TLS through rustls: with --tls-cert/--tls-key the coordinator only speaks TLS, a client
//! that trusts the CA gets through (with the token), a plain-text client does not.

mod common;

use common::*;
use gaitsweep_core::pb::{self, sweep_service_client::SweepServiceClient};
use std::path::Path;
use std::process::Command;
use tonic::transport::{Certificate, Channel, ClientTlsConfig};

fn openssl(dir: &Path, args: &[&str]) {
    let st = Command::new("openssl")
        .args(args)
        .current_dir(dir)
        .output()
        .expect("openssl is needed for this test");
    assert!(
        st.status.success(),
        "openssl {args:?}: {}",
        String::from_utf8_lossy(&st.stderr)
    );
}

/// A CA and a server certificate for localhost / 127.0.0.1 signed by it.
fn make_certs(dir: &Path) {
    openssl(
        dir,
        &[
            "req",
            "-x509",
            "-newkey",
            "rsa:2048",
            "-nodes",
            "-keyout",
            "ca.key",
            "-out",
            "ca.pem",
            "-days",
            "2",
            "-subj",
            "/CN=gaitsweep test ca",
        ],
    );
    openssl(
        dir,
        &[
            "req",
            "-newkey",
            "rsa:2048",
            "-nodes",
            "-keyout",
            "server.key",
            "-out",
            "server.csr",
            "-subj",
            "/CN=localhost",
        ],
    );
    std::fs::write(
        dir.join("ext.cnf"),
        "subjectAltName=DNS:localhost,IP:127.0.0.1\nbasicConstraints=CA:FALSE\n",
    )
    .unwrap();
    openssl(
        dir,
        &[
            "x509",
            "-req",
            "-in",
            "server.csr",
            "-CA",
            "ca.pem",
            "-CAkey",
            "ca.key",
            "-CAcreateserial",
            "-out",
            "server.pem",
            "-days",
            "2",
            "-extfile",
            "ext.cnf",
        ],
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn tls_with_token() {
    let tmp = tempfile::tempdir().unwrap();
    let certs = tmp.path().join("certs");
    std::fs::create_dir_all(&certs).unwrap();
    make_certs(&certs);
    let (cert, key) = (certs.join("server.pem"), certs.join("server.key"));
    let coord = Coord::start(
        tmp.path(),
        "127.0.0.1:0",
        &[
            "--token",
            "tls-token",
            "--tls-cert",
            cert.to_str().unwrap(),
            "--tls-key",
            key.to_str().unwrap(),
        ],
    )
    .await;
    let port = coord.addr.rsplit(':').next().unwrap().to_string();
    let url = format!("https://localhost:{port}");
    let ca = std::fs::read(certs.join("ca.pem")).unwrap();
    let ch = Channel::from_shared(url.clone())
        .unwrap()
        .tls_config(
            ClientTlsConfig::new()
                .ca_certificate(Certificate::from_pem(&ca))
                .domain_name("localhost"),
        )
        .unwrap()
        .connect()
        .await
        .expect("tls connect");
    let mut c = SweepServiceClient::new(ch);
    let mut req = tonic::Request::new(pb::ListSweepsRequest {});
    req.metadata_mut()
        .insert("authorization", "Bearer tls-token".parse().unwrap());
    assert!(c
        .list_sweeps(req)
        .await
        .unwrap()
        .into_inner()
        .sweeps
        .is_empty());
    assert_eq!(
        c.list_sweeps(pb::ListSweepsRequest {})
            .await
            .unwrap_err()
            .code(),
        tonic::Code::Unauthenticated
    );

    // plain text is refused
    let plain = Channel::from_shared(coord.url()).unwrap().connect().await;
    if let Ok(ch) = plain {
        assert!(SweepServiceClient::new(ch)
            .list_sweeps(pb::ListSweepsRequest {})
            .await
            .is_err());
    }

    // the CLI speaks TLS too
    let out = Command::new(bin("coordinator"))
        .args([
            "list",
            "--connect",
            &url,
            "--token",
            "tls-token",
            "--tls-ca",
            certs.join("ca.pem").to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "coordinator list over tls: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Fault-injection finding: a self-signed certificate from a plain `openssl req -x509`
/// (CA:TRUE) is refused by rustls as a server certificate; the CLI then asked "is it
/// running?" and the worker retried for ever as if the coordinator were unreachable. Both
/// must say what is wrong with the certificate, and the worker must stop.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_ca_certificate_as_server_certificate_is_named_not_retried() {
    let tmp = tempfile::tempdir().unwrap();
    let certs = tmp.path().join("certs");
    std::fs::create_dir_all(&certs).unwrap();
    openssl(
        &certs,
        &[
            "req",
            "-x509",
            "-newkey",
            "rsa:2048",
            "-nodes",
            "-keyout",
            "self.key",
            "-out",
            "self.pem",
            "-days",
            "2",
            "-subj",
            "/CN=localhost",
            "-addext",
            "subjectAltName=DNS:localhost,IP:127.0.0.1",
        ],
    );
    let (cert, key) = (certs.join("self.pem"), certs.join("self.key"));
    let coord = Coord::start(
        tmp.path(),
        "127.0.0.1:0",
        &[
            "--tls-cert",
            cert.to_str().unwrap(),
            "--tls-key",
            key.to_str().unwrap(),
        ],
    )
    .await;
    let port = coord.addr.rsplit(':').next().unwrap().to_string();
    let url = format!("https://localhost:{port}");
    let out = Command::new(bin("coordinator"))
        .args([
            "list",
            "--connect",
            &url,
            "--tls-ca",
            cert.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("CA:FALSE") && !err.contains("is it running"),
        "{err}"
    );

    let mut worker = Proc::spawn(
        "worker",
        &[
            "--connect".into(),
            url.clone(),
            "--tls-ca".into(),
            cert.display().to_string(),
            "--work-dir".into(),
            tmp.path().join("work").display().to_string(),
        ],
        tmp.path().join("worker.log"),
    );
    let status = wait_for(
        "the worker to give up",
        std::time::Duration::from_secs(30),
        || {
            let s = worker.child.try_wait().ok().flatten();
            async move { s }
        },
    )
    .await;
    let log = worker.log_text();
    assert!(!status.success(), "{log}");
    assert!(log.contains("CA:FALSE"), "{log}");
}
