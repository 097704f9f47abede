//! Unit tests of `crate::config`: the secret-file settings (flags, environment names,
//! reading, the password put into the database URL).

use std::path::Path;

use clap::{CommandFactory, FromArgMatches, Parser};

use super::{Config, ConfigError, database_url_with_password, insert_password, read_secret_file};

/// `truecut serve`'s flags on their own.
#[derive(Debug, Parser)]
struct Serve {
    #[command(flatten)]
    config: Config,
}

/// Parses `args` as `truecut serve`'s flags, the environment left out (the test process's
/// own TRUECUT_* or DATABASE_URL must not change what a test sees).
fn parse(args: &[&str]) -> Result<Config, clap::Error> {
    let matches = Serve::command()
        .mut_args(|a| a.env(None::<&'static str>))
        .try_get_matches_from(std::iter::once("serve").chain(args.iter().copied()))?;
    Serve::from_arg_matches(&matches).map(|s| s.config)
}

fn write(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn secret_file_flags_parse() {
    let c = parse(&[
        "--tokens-file",
        "/run/s/tokens",
        "--database-url",
        "postgres://truecut@db/truecut",
        "--database-password-file",
        "/run/s/db-password",
    ])
    .unwrap();
    assert_eq!(c.tokens_file.as_deref(), Some(Path::new("/run/s/tokens")));
    assert_eq!(
        c.database_password_file.as_deref(),
        Some(Path::new("/run/s/db-password"))
    );
    assert_eq!(c.tokens, None);
    let plain = parse(&[]).unwrap();
    assert_eq!(plain.tokens_file, None);
    assert_eq!(plain.database_password_file, None);
}

/// The environment names compose.yaml sets (clap reads them like the flags).
#[test]
fn secret_files_are_read_from_their_environment_names() {
    let command = Serve::command();
    let env_of = |id: &str| {
        command
            .get_arguments()
            .find(|a| a.get_id() == id)
            .and_then(|a| a.get_env())
            .map(|e| e.to_string_lossy().to_string())
    };
    assert_eq!(
        env_of("tokens_file").as_deref(),
        Some("TRUECUT_TOKENS_FILE")
    );
    assert_eq!(
        env_of("database_password_file").as_deref(),
        Some("TRUECUT_DATABASE_PASSWORD_FILE")
    );
    assert_eq!(env_of("tokens").as_deref(), Some("TRUECUT_TOKENS"));
}

#[test]
fn tokens_and_tokens_file_do_not_go_together() {
    let err = parse(&["--tokens", "a admin", "--tokens-file", "/x"]).unwrap_err();
    assert_eq!(
        err.kind(),
        clap::error::ErrorKind::ArgumentConflict,
        "{err}"
    );
}

#[test]
fn a_secret_file_loses_its_trailing_line_ends_only() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        ("lf", "s3cret\n", "s3cret"),
        ("crlf", "s3cret\r\n", "s3cret"),
        ("none", "s3cret", "s3cret"),
        ("blank-lines", "s3cret\n\n", "s3cret"),
        ("spaces-kept", " s3 cret \n", " s3 cret "),
    ];
    for (name, text, want) in cases {
        let path = write(dir.path(), name, text);
        assert_eq!(read_secret_file(&path, "tokens").unwrap(), want, "{name}");
    }
}

#[test]
fn an_empty_or_missing_secret_file_is_a_sentence() {
    let dir = tempfile::tempdir().unwrap();
    let empty = write(dir.path(), "empty", "\n");
    let err = read_secret_file(&empty, "database password").unwrap_err();
    assert!(matches!(err, ConfigError::Empty { .. }), "{err:?}");
    let text = err.to_string();
    assert!(
        text.contains("database password file") && text.contains(&empty.display().to_string()),
        "{text}"
    );

    let missing = dir.path().join("missing");
    let err = read_secret_file(&missing, "tokens").unwrap_err();
    assert!(matches!(err, ConfigError::Unreadable { .. }), "{err:?}");
    let text = err.to_string();
    assert!(
        text.starts_with("cannot read the tokens file")
            && text.contains(&missing.display().to_string())
            && text.contains("may read it"),
        "{text}"
    );
    // the cause is the error's source (shown once in a chain), not a part of its sentence
    assert!(
        std::error::Error::source(&err).is_some() && !text.contains("os error"),
        "{text}"
    );
}

#[test]
fn the_password_goes_into_the_user_part_percent_encoded() {
    assert_eq!(
        insert_password("postgres://truecut@db:5432/truecut", "abc123").unwrap(),
        "postgres://truecut:abc123@db:5432/truecut"
    );
    // every reserved character is encoded; unreserved ones stay
    assert_eq!(
        insert_password("postgresql://u@h/db?sslmode=require", "p@ss:w/rd%?#~._- é").unwrap(),
        "postgresql://u:p%40ss%3Aw%2Frd%25%3F%23~._-%20%C3%A9@h/db?sslmode=require"
    );
    // an '@' after the host (in the query) is not the user's
    assert_eq!(
        insert_password("postgres://u@h?options=a@b", "x").unwrap(),
        "postgres://u:x@h?options=a@b"
    );
    assert_eq!(
        insert_password("postgres://u@/db?host=/run/postgresql", "x").unwrap(),
        "postgres://u:x@/db?host=/run/postgresql"
    );
}

#[test]
fn a_url_that_cannot_take_the_password_is_refused() {
    let refused = [
        ("postgres://db:5432/truecut", "no user"),
        ("postgres://@db/truecut", "no user"),
        ("postgres://db/x?user=a@b", "no user"),
        ("postgres://u:old@db/truecut", "password twice"),
        ("sqlite://truecut.db", "not postgres"),
    ];
    for (url, why) in refused {
        let err = insert_password(url, "x").unwrap_err();
        let ok = match why {
            "no user" => matches!(err, ConfigError::NoUser),
            "password twice" => matches!(err, ConfigError::PasswordTwice),
            _ => matches!(err, ConfigError::PasswordWithoutPostgres),
        };
        assert!(ok, "{url}: {err:?}");
    }
}

#[test]
fn the_database_url_takes_the_file_password() {
    let dir = tempfile::tempdir().unwrap();
    let pw = write(dir.path(), "db-password", "9f86d081884c7d65\n");
    let config = parse(&[
        "--database-url",
        "postgres://truecut@db:5432/truecut",
        "--database-password-file",
        pw.to_str().unwrap(),
    ])
    .unwrap();
    assert_eq!(
        config.database_url_with_password().unwrap().as_deref(),
        Some("postgres://truecut:9f86d081884c7d65@db:5432/truecut")
    );
    // without a file the URL is used as given, and SQLite stays the default
    assert_eq!(
        database_url_with_password(Some("postgres://u:p@h/d"), None).unwrap(),
        Some("postgres://u:p@h/d".to_string())
    );
    assert_eq!(database_url_with_password(None, None).unwrap(), None);
    // a file without a URL to put it into
    let err = database_url_with_password(None, Some(&pw)).unwrap_err();
    assert!(
        matches!(err, ConfigError::PasswordWithoutPostgres),
        "{err:?}"
    );
    // the file is read when the URL is made: a missing one is a sentence then
    let err = database_url_with_password(Some("postgres://u@h/d"), Some(&dir.path().join("gone")))
        .unwrap_err();
    assert!(matches!(err, ConfigError::Unreadable { .. }), "{err:?}");
}

#[test]
fn the_tokens_come_from_the_file_or_the_setting() {
    let dir = tempfile::tempdir().unwrap();
    let file = write(dir.path(), "tokens", "a1b2c3 admin\nr3ad read\n");
    let from_file = parse(&["--tokens-file", file.to_str().unwrap()]).unwrap();
    assert_eq!(
        from_file.tokens_text().unwrap().as_deref(),
        Some("a1b2c3 admin\nr3ad read")
    );
    let inline = parse(&["--tokens", "s3cret admin"]).unwrap();
    assert_eq!(
        inline.tokens_text().unwrap().as_deref(),
        Some("s3cret admin")
    );
    assert_eq!(parse(&[]).unwrap().tokens_text().unwrap(), None);
    let missing = parse(&["--tokens-file", "/nonexistent/tokens"]).unwrap();
    assert!(matches!(
        missing.tokens_text().unwrap_err(),
        ConfigError::Unreadable { .. }
    ));
}
