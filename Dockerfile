# mesobake server image: build with the Rust toolchain, run on Debian slim as a non-root user.
#   docker build -t mesobake .
#   docker run -p 8080:8080 -v mesobake-data:/data mesobake
FROM rust:1.95-bookworm AS build
WORKDIR /src
COPY . .
RUN cargo build --release --locked --bin mesobake

FROM debian:bookworm-slim
# Mesa's software Vulkan driver lets previews render without a GPU; curl runs the health check.
RUN apt-get update \
    && apt-get install -y --no-install-recommends mesa-vulkan-drivers curl ca-certificates \
    && rm -rf /var/lib/apt/lists/* \
    && useradd --system --create-home --home-dir /home/mesobake mesobake \
    && mkdir /data && chown mesobake /data
COPY --from=build /src/target/release/mesobake /usr/local/bin/mesobake
USER mesobake
WORKDIR /data
ENV MESOBAKE_LISTEN=0.0.0.0:8080 \
    MESOBAKE_DATA_DIR=/data \
    MESOBAKE_DATABASE_URL=sqlite:///data/mesobake.sqlite \
    XDG_RUNTIME_DIR=/tmp
EXPOSE 8080
VOLUME /data
HEALTHCHECK --interval=30s --timeout=3s --start-period=10s \
    CMD curl -fsS http://127.0.0.1:8080/healthz || exit 1
ENTRYPOINT ["mesobake"]
CMD ["serve"]
