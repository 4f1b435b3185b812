//! Machine-readable reasons carried with gRPC errors (metadata `gaitsweep-reason`), so
//! clients recognise a condition by a key rather than by matching message text, and the
//! diagnosis of TLS failures that transports report as "unavailable".

/// Metadata key of the reason.
pub const KEY: &str = "gaitsweep-reason";
/// The worker id is not registered (e.g. the coordinator's database was replaced).
pub const UNKNOWN_WORKER: &str = "unknown-worker";
/// The coordinator's disk is full: a later retry may succeed once space is freed.
pub const DISK_FULL: &str = "disk-full";

/// The reason attached to a status, if any.
pub fn of(status: &tonic::Status) -> Option<&str> {
    status.metadata().get(KEY).and_then(|v| v.to_str().ok())
}

/// Attaches `reason` to `status`.
pub fn with(mut status: tonic::Status, reason: &'static str) -> tonic::Status {
    status
        .metadata_mut()
        .insert(KEY, tonic::metadata::MetadataValue::from_static(reason));
    status
}

/// If an error (or anything in its source chain) is a refused TLS certificate, says what
/// was wrong and what to do. Transports report these as "unavailable", which would
/// otherwise read as "the coordinator is not running" and be retried for ever.
pub fn tls_problem(err: &(dyn std::error::Error + 'static)) -> Option<String> {
    let mut chain = String::new();
    let mut e: Option<&(dyn std::error::Error + 'static)> = Some(err);
    while let Some(x) = e {
        chain.push_str(&format!("{x} / {x:?} / "));
        e = x.source();
    }
    let hint = if chain.contains("CaUsedAsEndEntity") {
        "the coordinator's certificate is a CA certificate (basicConstraints CA:TRUE, what a plain `openssl req -x509` makes); \
         a server certificate must be an end-entity one: sign a server certificate with your CA, or add \
         `-addext basicConstraints=critical,CA:FALSE -addext subjectAltName=DNS:HOST` (README \"TLS\")"
    } else if chain.contains("UnknownIssuer") {
        "the coordinator's certificate is not signed by the --tls-ca given: pass the CA that signed it"
    } else if chain.contains("NotValidForName") || chain.contains("NotValidForNameContext") {
        "the coordinator's certificate does not name the host in the URL: add it as a subjectAltName"
    } else if chain.contains("Expired") && chain.contains("certificate") {
        "the coordinator's certificate has expired: make a new one"
    } else if chain.contains("invalid peer certificate") || chain.contains("InvalidCertificate") {
        "the coordinator's certificate was refused"
    } else if chain.contains("InvalidContentType") || chain.contains("CorruptMessage") {
        "the coordinator does not speak TLS at this address: use http:// or start it with --tls-cert/--tls-key"
    } else {
        return None;
    };
    Some(format!("tls: {hint}"))
}
