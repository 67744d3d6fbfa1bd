// The SVA as one block (sim/cycle/readable/blocks/sva.py's boundary): descriptor row buffers for
// both views with the model's input flow control, the stages chained -- two matching-cost units,
// the box filter, the SGM path units and path sum, WTA with the sub-pixel step, the LR check --
// and the output register with valid/ready, the whole pipeline stalling (en low) while the
// output register holds a word the sink does not take (the model's stall).
//
// Boundary:
// - in_valid / in_ready / dl, dr, pix: one left/right descriptor pair (and the left pixel) in
//   raster order; taken (a joint pop) when in_valid && in_ready. in_ready is the ring's room
//   (the model's sva_rows_done_before_input): input row y_in may enter while y_in <= yb_done +
//   r + 1, yb_done the box rows whose every slot has been issued (the oldest row still read is
//   yb_done - r - 1, and the ring holds 2r + 3), or while y_in <= 2r + 2 (no row before the
//   frame's row 0 is read). The input side does not stall with the pipeline.
// - out_valid / out_ready / word: the output register; a word leaves when both are high.
// - run-time registers: width, height, k (box, odd, <= K_MAX), p1, p2, adaptive, slope, paths,
//   uniq, mode (sub-pixel), lr_on, max_diff, med_on, ii (the pipeline's II in ticks: the spacing of
//   emitting slots, and the LR check's drain cadence), sii (the slot II: the spacing of any two
//   slots, the matching cost's and box filter's II).
//
// Structure (the cycles come from it; no register is added to meet a number):
// - row buffers: a ring of NR = K_MAX + 2 rows per view (the box's k + 1 rows, y - 1 - r ..
//   y + r, and the row arriving), register arrays written at the input; an issued slot's
//   descriptors (and the right windows' new column) are read into the slot register: one
//   cycle before the matching cost that the model does not count (the row buffers' read);
// - the slot sequencer (moves only with en): a frame starts with k - 1 passes over its columns
//   that add rows clamp(-r) .. r - 1 into the column sums (the first fresh), then per box row y
//   W + r slots: columns 0 .. W - 1 adding row min(y + r, H - 1) and, y > 0, subtracting row
//   max(y - 1 - r, 0) (row 0 adds row min(r, H - 1): the k-th pass), each emitting pixel
//   col - r once col >= r, then r slots re-entering column W - 1 (the right border). A slot
//   needs its added row complete and waits sii ticks after the previous slot; an emitting slot
//   also ii ticks after the previous emitting one;
// - per slot two matching-cost units (sva_hamming): the cost of the row entering the vertical
//   window and of the row leaving it, each fed by a right window of D descriptors shifted one
//   column per slot (the plan's right window, twice: open finding 6); every slot goes through
//   them, so that every slot reaches the box filter the same ticks after its issue;
// - every stage takes the pipeline's en (every register holds while it stalls; sva_hamming
//   gained it for this top -- holding its input alone could not stall it);
// - the slot's control travels beside the costs in a small queue (pushed at the costs'
//   issue, popped as the box filter takes them);
// - box filter -> SGM (grey levels read from the left pixels' ring for the pixel it emits) ->
//   WTA -> LR check (the S vector waits for the WTA's word in a queue: open finding 7) ->
//   median (K_MED, on/off: after the frame's words, M W + M flush slots, each as soon as the
//   median takes it -- one a tick, with ONE_PORT one every second tick; its stream is skewed
//   by M W + M slots) -> output register. overrun flags a box pixel the SGM was not ready for
//   (a slot paced faster than its recurrence).
// - ONE_PORT: the box filter's, the SGM's and the median's memories single-port (sva.sram_ports
//   = 1rw: their IIs 2 G, 2 G and 2, which the sii and ii registers then carry); the row
//   buffers are a bank per row and view either way (a slot reads two rows, the input writes
//   a third).
module sva_top #(
    parameter int D = 16,        // disparities
    parameter int LANES = 16,
    parameter int V = 8,
    parameter int B = 32,        // descriptor bits (one part)
    parameter int K_MAX = 3,     // largest box
    parameter int W_MAX = 32,
    parameter int COST_W = 6,    // a matching cost: <= B
    parameter int A_W = 9,       // sva.cost_bits
    parameter int PATH_W = 12,   // sva.path_bits
    parameter int SUM_W = 13,    // sva.sum_bits
    parameter int F = 4,         // sub-pixel bits
    parameter int DB = 4,        // bits of d
    parameter int WB = 1 + DB + F,
    parameter int K_MED = 3,     // the median's window (med_on)
    parameter bit ONE_PORT = 0   // the stages' memories: 0 a read and a write port, 1 one
) (
    input  logic           clk,
    input  logic           rst,
    input  logic [7:0]     width,
    input  logic [7:0]     height,
    input  logic [3:0]     k,
    input  logic [14:0]    p1,
    input  logic [14:0]    p2,
    input  logic           adaptive,
    input  logic [14:0]    slope,
    input  logic [2:0]     paths,
    input  logic [6:0]     uniq,
    input  logic [1:0]     mode,
    input  logic           lr_on,
    input  logic           med_on,
    input  logic [7:0]     max_diff,
    input  logic [7:0]     ii,
    input  logic [7:0]     sii,
    input  logic           in_valid,
    output logic           in_ready,
    input  logic [B-1:0]   dl,
    input  logic [B-1:0]   dr,
    input  logic [7:0]     pix,
    output logic           out_valid,
    input  logic           out_ready,
    output logic [WB-1:0]  word,
    output logic           overrun
);
  localparam int NR = K_MAX + 2;
  localparam int XW = $clog2(W_MAX);
  localparam int G = (D + LANES - 1) / LANES;

  // the lock-step pipeline advances unless the output register holds a word not taken
  wire en = !(out_valid && !out_ready);
  wire [3:0] r = k >> 1;

  // ---- row buffers and the input side ------------------------------------------------------
  logic [B-1:0] ring_l [NR][W_MAX];
  logic [B-1:0] ring_r [NR][W_MAX];
  logic [7:0]   ring_p [NR][W_MAX];
  logic [7:0]   x_in, y_in;        // the next pair's column and row
  logic [7:0]   yb_done;           // box rows whose slots are all issued
  wire  [7:0]   rows_in = y_in;    // input rows complete
  assign in_ready = (y_in < height) && ((int'(y_in) <= int'(yb_done) + int'(r) + 1) ||
                                         (int'(y_in) <= 2 * int'(r) + 2));
  always_ff @(posedge clk) begin
    if (rst) begin
      x_in <= '0; y_in <= '0;
    end else if (in_valid && in_ready) begin
      ring_l[int'(y_in) % NR][x_in[XW-1:0]] <= dl;
      ring_r[int'(y_in) % NR][x_in[XW-1:0]] <= dr;
      ring_p[int'(y_in) % NR][x_in[XW-1:0]] <= pix;
      if (x_in == width - 1'b1) begin
        x_in <= '0; y_in <= y_in + 1'b1;
      end else begin
        x_in <= x_in + 1'b1;
      end
    end
  end

  // ---- the slot sequencer ----------------------------------------------------------------
  logic        passing;            // in the frame's first passes
  logic [3:0]  pass;               // pass index 0 .. k - 2 (adds row clamp(pass - r))
  logic [7:0]  yb;                 // the box row
  logic [7:0]  sc;                 // slot in the pass (column) or the row (0 .. W + r - 1)
  logic        done;
  logic [7:0]  since;              // ticks since the last emitting slot (saturating)
  logic [7:0]  since_slot;         // ticks since the last slot (saturating)
  logic [7:0]  ya, ys;             // the rows added and subtracted
  logic        s_upd, s_fresh, s_fill, s_emit, s_nosub;
  always_comb begin
    if (passing) begin
      ya = (int'(pass) < int'(r)) ? 8'd0 : 8'(int'(pass) - int'(r));
      if (int'(ya) > int'(height) - 1) ya = height - 1'b1;
      ys = '0;
      s_upd = 1'b1; s_fresh = (pass == 0); s_fill = (sc == 0); s_emit = 1'b0; s_nosub = 1'b1;
    end else begin
      ya = (int'(yb) + int'(r) > int'(height) - 1) ? height - 1'b1 : 8'(int'(yb) + int'(r));
      ys = (int'(yb) < int'(r) + 1) ? 8'd0 : 8'(int'(yb) - int'(r) - 1);
      s_upd = (sc < width); s_fresh = 1'b0; s_fill = (sc == 0);
      s_emit = (sc >= 8'(r)); s_nosub = (yb == 0);
    end
  end
  wire        k_one = (k <= 4'd1);   // no passes when k = 1
  wire        slot_ok = !done && (rows_in > ya) && (since_slot >= sii) &&
                        (!s_emit || since >= ii);
  wire        issue = en && slot_ok;
  wire [XW-1:0] col = s_upd ? sc[XW-1:0] : XW'(int'(width) - 1);

  // the slot register and the right windows (shifted at each updating slot)
  logic            sl_v, sl_upd, sl_fresh, sl_fill, sl_emit, sl_nosub;
  logic [XW-1:0]   sl_col;
  logic [B-1:0]    sl_dla, sl_dls;
  logic [D*B-1:0]  wa, ws;         // right windows: w[d] = right descriptor at col - d
  logic [D-1:0]    oa;             // col - d < 0
  always_ff @(posedge clk) begin
    if (rst) begin
      passing <= 1'b1; pass <= '0; yb <= '0; sc <= '0; done <= 1'b0; since <= 8'hff;
      since_slot <= 8'hff;
      yb_done <= '0; sl_v <= 1'b0;
    end else if (en) begin
      if (k_one && passing) passing <= 1'b0;
      sl_v <= issue;
      since <= issue && s_emit ? 8'd1 : ((since == 8'hff) ? since : since + 1'b1);
      since_slot <= issue ? 8'd1 : ((since_slot == 8'hff) ? since_slot : since_slot + 1'b1);
      if (issue) begin
        sl_upd <= s_upd; sl_fresh <= s_fresh; sl_fill <= s_fill; sl_emit <= s_emit;
        sl_nosub <= s_nosub; sl_col <= col;
        if (s_upd) begin
          sl_dla <= ring_l[int'(ya) % NR][col];
          sl_dls <= ring_l[int'(ys) % NR][col];
          wa <= {wa[(D-1)*B-1:0], ring_r[int'(ya) % NR][col]};
          ws <= {ws[(D-1)*B-1:0], ring_r[int'(ys) % NR][col]};
          for (int d = 0; d < D; d++) oa[d] <= (d > int'(col));
        end
        if (passing) begin
          if (sc == width - 1'b1) begin
            sc <= '0;
            if (int'(pass) == int'(k) - 2) passing <= 1'b0;
            pass <= pass + 1'b1;
          end else sc <= sc + 1'b1;
        end else if (int'(sc) == int'(width) + int'(r) - 1) begin
          sc <= '0; yb <= yb + 1'b1; yb_done <= yb + 1'b1;
          if (yb == height - 1'b1) done <= 1'b1;
        end else sc <= sc + 1'b1;
      end
    end
  end

  // ---- the two matching-cost units (every slot goes through them) ------------------------
  wire             h_v = sl_v;
  wire [B-1:0]     h_la = sl_dla, h_ls = sl_dls;
  wire [D*B-1:0]   h_wa = wa, h_ws = ws;
  wire [D-1:0]     h_o = oa;
  logic               ca_v, cs_v, ca_rdy, cs_rdy;
  logic [D*COST_W-1:0] ca, cs;
  sva_hamming #(.D(D), .LANES(LANES), .V(V), .B0(B), .B1(0), .COST_W(COST_W)) u_cost_add (
      .clk(clk), .rst(rst), .en(en), .in_valid(h_v), .in_ready(ca_rdy), .dl(h_la), .dr(h_wa),
      .outside(h_o), .w0(2'd1), .w1(2'd0), .out_valid(ca_v), .cost(ca));
  sva_hamming #(.D(D), .LANES(LANES), .V(V), .B0(B), .B1(0), .COST_W(COST_W)) u_cost_sub (
      .clk(clk), .rst(rst), .en(en), .in_valid(h_v), .in_ready(cs_rdy), .dl(h_ls), .dr(h_ws),
      .outside(h_o), .w0(2'd1), .w1(2'd0), .out_valid(cs_v), .cost(cs));

  // ---- the slots' control beside the costs: a queue (non-updating slots skip the costs) ----
  localparam int QD = 8;
  logic [XW+4:0]  cq [QD];          // {col, upd, fresh, fill, emit, nosub}
  logic [2:0]     cq_w, cq_r;
  wire            box_rdy;
  wire [XW+4:0]   cq_head = cq[cq_r];
  wire            head_upd = cq_head[4];
  wire            cq_empty = (cq_w == cq_r);
  // the box takes the head when its costs are out (every slot goes through the cost units:
  // the ones without an update carry no cost, but the same latency)
  wire            bx_v = !cq_empty && ca_v;
  wire            bx_take = en && bx_v && box_rdy;
  always_ff @(posedge clk) begin
    if (rst) begin
      cq_w <= '0; cq_r <= '0;
    end else if (en) begin
      if (sl_v) begin
        cq[cq_w] <= {sl_col, sl_upd, sl_fresh, sl_fill, sl_emit, sl_nosub};
        cq_w <= cq_w + 1'b1;
      end
      if (bx_take) cq_r <= cq_r + 1'b1;
    end
  end

  // ---- the box filter ---------------------------------------------------------------------
  logic              bo_v;
  logic [D*A_W-1:0]  agg;
  sva_box #(.D_MAX(D), .LANES(LANES), .V(V), .K_MAX(K_MAX), .W_MAX(W_MAX), .COST_W(COST_W),
            .A_W(A_W), .ONE_PORT(ONE_PORT)) u_box (
      .clk(clk), .rst(rst), .en(en), .ngroups(8'(G)), .k(k), .in_valid(bx_v),
      .in_ready(box_rdy), .col(cq_head[XW+4:5]), .upd(head_upd), .fresh(cq_head[3]),
      .fill(cq_head[2]), .emit(cq_head[1]),
      .c_add(head_upd ? ca : '0), .c_sub((head_upd && !cq_head[0]) ? cs : '0),
      .out_valid(bo_v), .agg(agg));

  // ---- SGM and path sum: the emitted pixel's grey levels from the left pixels' ring --------
  logic [7:0] xo, yo;               // the pixel the box filter emits next
  always_ff @(posedge clk) begin
    if (rst) begin
      xo <= '0; yo <= '0;
    end else if (en && bo_v) begin
      if (xo == width - 1'b1) begin xo <= '0; yo <= yo + 1'b1; end
      else xo <= xo + 1'b1;
    end
  end
  wire [7:0] yu = (yo == 0) ? 8'd0 : yo - 1'b1;
  wire [7:0] xl = (xo == 0) ? 8'd0 : xo - 1'b1;
  wire [7:0] xr = (xo == width - 1'b1) ? xo : xo + 1'b1;
  wire [7:0] grey = ring_p[int'(yo) % NR][xo[XW-1:0]];
  wire [23:0] grey_up = {ring_p[int'(yu) % NR][xr[XW-1:0]], ring_p[int'(yu) % NR][xo[XW-1:0]],
                         ring_p[int'(yu) % NR][xl[XW-1:0]]};
  logic                sg_rdy, lc_v, s_v;
  logic [4*D*PATH_W-1:0] lc;
  logic [D*SUM_W-1:0]  s;
  sva_sgm #(.D_MAX(D), .LANES(LANES), .V(V), .W_MAX(W_MAX), .A_W(A_W), .PATH_W(PATH_W),
            .SUM_W(SUM_W), .ONE_PORT(ONE_PORT)) u_sgm (
      .clk(clk), .rst(rst), .en(en), .ngroups(8'(G)), .dn(9'(D)), .width(width), .p1(p1),
      .p2(p2), .adaptive(adaptive), .slope(slope), .paths(paths), .in_valid(bo_v),
      .in_ready(sg_rdy), .a(agg), .grey(grey), .grey_up(grey_up), .x_first(xo == 0),
      .x_last(xo == width - 1'b1), .y_first(yo == 0), .lc_valid(lc_v), .lc(lc),
      .s_valid(s_v), .s(s));
  always_ff @(posedge clk) begin
    if (rst) overrun <= 1'b0;
    else if (en && bo_v && !sg_rdy) overrun <= 1'b1;
  end

  // ---- WTA, the S vectors waiting for its words, the LR check ------------------------------
  logic             wt_rdy, wt_v;
  logic [WB-1:0]    q;
  logic [DB-1:0]    dstar;
  logic [SUM_W-1:0] s1;
  sva_wta #(.D(D), .LANES(LANES), .V(V), .SW(SUM_W), .F(F), .DB(DB)) u_wta (
      .clk(clk), .rst(rst), .en(en), .in_valid(s_v), .in_ready(wt_rdy), .s_in(s),
      .uniq(uniq), .mode(mode), .out_valid(wt_v), .q(q), .dstar(dstar), .s1(s1));
  localparam int SQ = 16;
  logic [D*SUM_W-1:0] sq [SQ];
  logic [3:0]         sq_w, sq_r;
  always_ff @(posedge clk) begin
    if (rst) begin
      sq_w <= '0; sq_r <= '0;
    end else if (en) begin
      if (s_v) begin sq[sq_w] <= s; sq_w <= sq_w + 1'b1; end
      if (wt_v) sq_r <= sq_r + 1'b1;
    end
  end
  logic          lr_v;
  logic [WB-1:0] lr_q;
  sva_lr #(.D(D), .SW(SUM_W), .DB(DB), .WB(WB), .XW(8)) u_lr (
      .clk(clk), .rst(rst), .en(en && lr_on), .in_valid(wt_v), .s_in(sq[sq_r]), .q_in(q),
      .d_in(dstar), .width(width), .ii(ii), .max_diff(max_diff), .out_valid(lr_v),
      .q_out(lr_q));

  // ---- the median (med_on): the words, then M W + M flush slots, each as soon as the median
  // takes it (one a tick; with single-port row banks one every second tick: its in_ready) ----
  localparam int MM = K_MED / 2;
  wire           pre_v = lr_on ? lr_v : wt_v;
  wire [WB-1:0]  pre_q = lr_on ? lr_q : q;
  logic [15:0]   words_in, flush;
  logic          med_rdy;
  wire           frame_in = (int'(words_in) == int'(width) * int'(height));
  wire           flushing = frame_in && (int'(flush) < MM * int'(width) + MM) && med_rdy;
  always_ff @(posedge clk) begin
    if (rst) begin
      words_in <= '0; flush <= '0;
    end else if (en) begin
      if (pre_v) words_in <= words_in + 1'b1;
      if (flushing) flush <= flush + 1'b1;
    end
  end
  logic          md_v;
  logic [WB-1:0] md_q;
  localparam int MXW = $clog2(W_MAX + 1);  // a column counter that holds W_MAX
  sva_median #(.K(K_MED), .V(V), .WB(WB), .WMAX(W_MAX), .XW(MXW), .YW(6),
               .ONE_PORT(ONE_PORT)) u_median (
      .clk(clk), .rst(rst), .en(en && med_on), .in_valid(pre_v || flushing), .in_ready(med_rdy),
      .word(pre_q),
      .width(MXW'(width)), .height(6'(height)), .out_valid(md_v), .med(md_q));

  // ---- the output register --------------------------------------------------------------
  always_ff @(posedge clk) begin
    if (rst) out_valid <= 1'b0;
    else if (en) begin
      out_valid <= med_on ? md_v : pre_v;
      word <= med_on ? md_q : pre_q;
    end
  end
endmodule
