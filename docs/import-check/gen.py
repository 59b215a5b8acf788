#!/usr/bin/env python3
"""User-shaped pendulum recordings for fuzzing `koopman import` / `estimate`.

Writes $FUZZ_ROOT/<category>/<name> and $FUZZ_MANIFEST (docs/import-check/run.sh sets both)
(one entry per file: path, category, format, truth L/Q/offset/amp/rate/
duration, extra CLI args the user would pass, whether it is well formed).
Pure Python (no numpy). Deterministic (seed argument, default 1).
"""
import io, json, math, os, random, shutil, sys, zipfile

ROOT = os.environ['FUZZ_ROOT']
G = 9.81
MAN = []


# ---------------------------------------------------------------- physics
def simulate(L, Q, amp, rate, dur, offset=0.0, noise=0.001, rng=None, t0=0.0,
             jitter=0.0):
    """Damped pendulum theta'' = -g/L sin th - c th', c = w0/Q.
    Returns lists t, theta_meas (offset + noise), omega (true rate)."""
    rng = rng or random.Random(0)
    w0 = math.sqrt(G / L)
    c = w0 / Q
    n = int(round(dur * rate)) + 1
    ts = [t0 + k / rate for k in range(n)]
    if jitter:
        ts = [t0 + k / rate + (rng.uniform(-jitter, jitter) / rate if k else 0) for k in range(n)]
    # RK4 on a fine step, read at the stamps by stepping exactly to each
    def f(th, om):
        return om, -w0 * w0 * math.sin(th) - c * om
    th, om = amp, 0.0
    cur = t0
    hmax = min(0.002, 0.02 / w0)
    TH, OM = [], []
    for t in ts:
        while cur < t - 1e-12:
            h = min(hmax, t - cur)
            k1 = f(th, om)
            k2 = f(th + h / 2 * k1[0], om + h / 2 * k1[1])
            k3 = f(th + h / 2 * k2[0], om + h / 2 * k2[1])
            k4 = f(th + h * k3[0], om + h * k3[1])
            th += h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
            om += h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
            cur += h
        TH.append(th + offset + rng.gauss(0, noise))
        OM.append(om)
    return ts, TH, OM


def rand_params(rng, rate=None, dur=None, L=None):
    L = L if L is not None else round(rng.uniform(0.1, 1.5), 4)
    Q = round(math.exp(rng.uniform(math.log(30), math.log(1000))), 1)
    off = round(rng.uniform(0.01, 0.06) * rng.choice([-1, 1]), 4)
    amp = round(rng.uniform(0.1, 0.8), 3)
    rate = rate if rate is not None else rng.choice([5, 10, 12, 25, 30, 50, 60, 100, 120, 200, 240, 500])
    dur = dur if dur is not None else rng.choice([5, 10, 20, 30, 60, 120])
    return dict(L=L, Q=Q, offset=off, amp=amp, rate=rate, duration=dur)


# ---------------------------------------------------------------- writers
def E(x):  # phyphox / Tracker (Java) number style 9.969000006E-3, 9.620000000E2
    m, e = ('%.9E' % x).split('E')
    return '%sE%d' % (m, int(e))


def dc(s):  # decimal comma
    return s.replace('.', ',')


def out(cat, name, data, truth=None, good=False, fmt='', args=None, note=''):
    d = os.path.join(ROOT, cat)
    os.makedirs(d, exist_ok=True)
    p = os.path.join(d, name)
    mode = 'wb' if isinstance(data, (bytes, bytearray)) else 'w'
    kw = {} if mode == 'wb' else dict(newline='', encoding='utf-8')
    with open(p, mode, **kw) as fh:
        fh.write(data)
    MAN.append(dict(path=p, category=cat, format=fmt, good=good, truth=truth,
                    args=args or [], note=note))
    return p


def rows_text(header, rows, sep=',', eol='\n', decimal_comma=False, bom=False, quote=False):
    def q(s):
        return '"%s"' % s if quote else s
    lines = [sep.join(q(h) for h in header)] if header is not None else []
    for r in rows:
        cells = []
        for v in r:
            s = v if isinstance(v, str) else repr(float(v))
            if decimal_comma:
                s = dc(s)
            cells.append(s)
        lines.append(sep.join(cells))
    txt = eol.join(lines) + eol
    return ('\ufeff' if bom else '') + txt


# --- tool formats: each returns (text-or-bytes, ext)
def f_plain(t, th, om, **k):
    return rows_text(['t', 'theta'], [(a, b) for a, b in zip(t, th)]), 'csv'


def gyro_rows(t, om, rng, bias=0.01):
    # phone as the bob: swing on z, a little leakage on x, y
    rows = []
    for a, w in zip(t, om):
        gx = 0.03 * w + rng.gauss(0, 0.003) + 0.002
        gy = -0.02 * w + rng.gauss(0, 0.003) - 0.001
        gz = w + rng.gauss(0, 0.003) + bias
        rows.append((a, gx, gy, gz, math.sqrt(gx * gx + gy * gy + gz * gz)))
    return rows


PH_HDR = ['Time (s)', 'Gyroscope x (rad/s)', 'Gyroscope y (rad/s)', 'Gyroscope z (rad/s)', 'Absolute (rad/s)']


def f_phyphox(t, th, om, sep=',', decimal_comma=False, rng=None, **k):
    rows = [[E(v) for v in r] for r in gyro_rows(t, om, rng)]
    return rows_text(PH_HDR, rows, sep=sep, decimal_comma=decimal_comma, quote=True), 'csv'


def xlsx_bytes(sheets):
    """sheets: list of (name, header list, rows of numbers/str/None)."""
    b = io.BytesIO()
    z = zipfile.ZipFile(b, 'w', zipfile.ZIP_DEFLATED)
    strings = []
    def si(s):
        if s not in strings:
            strings.append(s)
        return strings.index(s)
    def col(i):
        s = ''
        i += 1
        while i:
            i, r = divmod(i - 1, 26)
            s = chr(65 + r) + s
        return s
    sheet_xml = []
    for name, header, rows in sheets:
        xs = ['<?xml version="1.0" encoding="UTF-8" standalone="yes"?>',
              '<worksheet xmlns="http://schemas.openxmlformats.org/spreadsheetml/2006/main"><sheetData>']
        allrows = ([header] if header else []) + rows
        for ri, r in enumerate(allrows):
            cells = []
            for ci, v in enumerate(r):
                ref = '%s%d' % (col(ci), ri + 1)
                if v is None:
                    continue
                if isinstance(v, str):
                    if v.startswith('#'):
                        cells.append('<c r="%s" t="e"><v>%s</v></c>' % (ref, v))
                    else:
                        cells.append('<c r="%s" t="s"><v>%d</v></c>' % (ref, si(v)))
                else:
                    cells.append('<c r="%s"><v>%s</v></c>' % (ref, repr(float(v))))
            xs.append('<row r="%d">%s</row>' % (ri + 1, ''.join(cells)))
        xs.append('</sheetData></worksheet>')
        sheet_xml.append('\n'.join(xs))
    n = len(sheets)
    z.writestr('[Content_Types].xml',
               '<?xml version="1.0" encoding="UTF-8" standalone="yes"?><Types xmlns="http://schemas.openxmlformats.org/package/2006/content-types">'
               '<Default Extension="rels" ContentType="application/vnd.openxmlformats-package.relationships+xml"/>'
               '<Default Extension="xml" ContentType="application/xml"/>'
               '<Override PartName="/xl/workbook.xml" ContentType="application/vnd.openxmlformats-officedocument.spreadsheetml.sheet.main+xml"/>'
               + ''.join('<Override PartName="/xl/worksheets/sheet%d.xml" ContentType="application/vnd.openxmlformats-officedocument.spreadsheetml.worksheet+xml"/>' % (i + 1) for i in range(n))
               + '<Override PartName="/xl/sharedStrings.xml" ContentType="application/vnd.openxmlformats-officedocument.spreadsheetml.sharedStrings+xml"/>'
               '</Types>')
    z.writestr('_rels/.rels',
               '<?xml version="1.0" encoding="UTF-8" standalone="yes"?><Relationships xmlns="http://schemas.openxmlformats.org/package/2006/relationships">'
               '<Relationship Id="rId1" Type="http://schemas.openxmlformats.org/officeDocument/2006/relationships/officeDocument" Target="xl/workbook.xml"/></Relationships>')
    z.writestr('xl/workbook.xml',
               '<?xml version="1.0" encoding="UTF-8" standalone="yes"?><workbook xmlns="http://schemas.openxmlformats.org/spreadsheetml/2006/main" xmlns:r="http://schemas.openxmlformats.org/officeDocument/2006/relationships"><sheets>'
               + ''.join('<sheet name="%s" sheetId="%d" r:id="rId%d"/>' % (s[0], i + 1, i + 1) for i, s in enumerate(sheets))
               + '</sheets></workbook>')
    z.writestr('xl/_rels/workbook.xml.rels',
               '<?xml version="1.0" encoding="UTF-8" standalone="yes"?><Relationships xmlns="http://schemas.openxmlformats.org/package/2006/relationships">'
               + ''.join('<Relationship Id="rId%d" Type="http://schemas.openxmlformats.org/officeDocument/2006/relationships/worksheet" Target="worksheets/sheet%d.xml"/>' % (i + 1, i + 1) for i in range(n))
               + '<Relationship Id="rId%d" Type="http://schemas.openxmlformats.org/officeDocument/2006/relationships/sharedStrings" Target="sharedStrings.xml"/>' % (n + 1)
               + '</Relationships>')
    for i, x in enumerate(sheet_xml):
        z.writestr('xl/worksheets/sheet%d.xml' % (i + 1), x)
    z.writestr('xl/sharedStrings.xml',
               '<?xml version="1.0" encoding="UTF-8" standalone="yes"?><sst xmlns="http://schemas.openxmlformats.org/spreadsheetml/2006/main" count="%d" uniqueCount="%d">' % (len(strings), len(strings))
               + ''.join('<si><t>%s</t></si>' % s.replace('&', '&amp;').replace('<', '&lt;') for s in strings) + '</sst>')
    z.close()
    return b.getvalue()


def f_phyphox_xlsx(t, th, om, rng=None, **k):
    rows = [list(r) for r in gyro_rows(t, om, rng)]
    return xlsx_bytes([('Gyroscope', PH_HDR, rows),
                       ('Metadata Device', ['property', 'value'], [['model', 'Pixel 7']]),
                       ('Metadata Time', ['event', 'experiment time'], [['START', 0.0], ['PAUSE', t[-1]]])]), 'xlsx'


def f_phyphox_zip(t, th, om, rng=None, **k):
    txt, _ = f_phyphox(t, th, om, rng=rng)
    b = io.BytesIO()
    z = zipfile.ZipFile(b, 'w', zipfile.ZIP_DEFLATED)
    z.writestr('Gyroscope.csv', txt)
    z.writestr('meta/device.csv', '"property","value"\n"deviceModel","Pixel 7"\n')
    z.writestr('meta/time.csv', '"event","experiment time","system time","system time text"\n"START",0.000000000E0,1.7E9,"2024-01-01 10:00:00.000 UTC+01:00"\n')
    z.close()
    return b.getvalue(), 'zip'


def f_tracker_xy(t, th, om, L=None, rng=None, **k):
    # pixels, y up, pivot off origin, scale 600 px/m capped
    scale = min(600.0, 700.0 / L)
    px, py = 640.0 + rng.uniform(-50, 50), 900.0 + rng.uniform(-50, 50)
    rows = []
    for a, b in zip(t, th):
        x = px + L * scale * math.sin(b) + rng.gauss(0, 0.3)
        y = py - L * scale * math.cos(b) + rng.gauss(0, 0.3)
        rows.append((E(a), E(x), E(y)))
    return 'mass_A\n' + rows_text(['t', 'x', 'y'], rows, sep='\t'), 'txt'


def f_tracker_theta(t, th, om, name='theta', **k):
    return 'mass_A\n' + rows_text(['t', name], [(E(a), E(b)) for a, b in zip(t, th)], sep='\t'), 'txt'


def f_vernier(t, th, om, deg=True, **k):
    s = 180 / math.pi if deg else 1.0
    u = '°' if deg else 'rad'
    hdr = ['Latest: Time (s)', 'Latest: Angle (%s)' % u, 'Latest: Angular Velocity (%s/s)' % u]
    rows = [('%.3f' % a, '%.4f' % (b * s), '%.4f' % (w * s)) for a, b, w in zip(t, th, om)]
    return rows_text(hdr, rows, quote=True), 'csv'


def f_pasco(t, th, om, deg=False, runs=1, rng=None, params=None, **k):
    s = 180 / math.pi if deg else 1.0
    u = '°' if deg else 'rad'
    hdr, cols = [], []
    for r in range(1, runs + 1):
        hdr += ['Time (s) Run #%d' % r, 'Angle (%s) Run #%d' % (u, r), 'Angular Velocity (%s/s) Run #%d' % (u, r)]
        if r == 1:
            tt, a, w = t, th, om
        else:  # a shorter second run of the same rig
            p = params
            tt, a, w = simulate(p['L'], p['Q'], p['amp'] * 0.8, p['rate'], p['duration'] * 0.7, p['offset'], rng=rng)
        cols.append([('%.4f' % x, '%.5f' % (y * s), '%.5f' % (z * s)) for x, y, z in zip(tt, a, w)])
    n = max(len(c) for c in cols)
    rows = []
    for i in range(n):
        r = []
        for c in cols:
            r += list(c[i]) if i < len(c) else ['', '', '']
        rows.append(r)
    return rows_text(hdr, rows, sep='\t', eol='\r\n', decimal_comma=True, bom=True), 'txt'


def f_encoder(t, th, om, rate=None, duration=None, **k):
    trig = round(th[0] * 180 / math.pi)
    lines = ['trigger_start_deg, sample_rate, duration_sec', '%d, %d, %d ' % (trig, rate, duration)]
    lines += ['%.2f' % (b * 180 / math.pi) for b in th]
    return '\n'.join(lines) + '\n', 'txt'


def encoder_events(t, th, counts_per_turn=4000):
    """One row per count change, stamped when it happened (uneven)."""
    q = 2 * math.pi / counts_per_turn
    rows = []
    last = math.floor(th[0] / q)
    rows.append((t[0], last))
    for i in range(1, len(t)):
        c = math.floor(th[i] / q)
        if c != last:
            step = 1 if c > last else -1
            k = last
            while k != c:
                k += step
                # linear interpolation of the crossing time
                thr = (k if step > 0 else k + 1) * q
                f = (thr - th[i - 1]) / (th[i] - th[i - 1]) if th[i] != th[i - 1] else 0.5
                rows.append((t[i - 1] + f * (t[i] - t[i - 1]), k))
            last = c
    return rows, q


def f_encoder_events(t, th, om, **k):
    rows, q = encoder_events(t, th)
    return rows_text(['time (s)', 'angle (deg)'], [('%.6f' % a, '%.2f' % (c * q * 180 / math.pi)) for a, c in rows]), 'csv'


def f_imu(t, th, om, rng=None, **k):
    pre = ['Input type: live', 'Opening phidget object....', 'Waiting for attach....', 'Spatial 302088 Attached!',
           'Number of Acceleration Axes: 3', 'Number of Gyro Axes: 3']
    lines = list(pre)
    for a, w in zip(t, om):
        g = [rng.gauss(0, 0.3), rng.gauss(0, 0.3), w * 180 / math.pi + rng.gauss(0, 0.3) + 0.5]
        lines.append('[%r, %.5f, %.5f, %.5f, %.4f, %.4f, %.4f]' % (a, rng.gauss(0, .01), rng.gauss(-1, .01), rng.gauss(0, .01), *g))
    return '\n'.join(lines) + '\n', 'txt'


FORMATS = {
    'plain_csv': (f_plain, {}, []),
    'phyphox_comma': (f_phyphox, dict(sep=','), []),
    'phyphox_tab_deccomma': (f_phyphox, dict(sep='\t', decimal_comma=True), []),
    'phyphox_semicolon_deccomma': (f_phyphox, dict(sep=';', decimal_comma=True), []),
    'phyphox_semicolon_point': (f_phyphox, dict(sep=';'), []),
    'phyphox_xlsx': (f_phyphox_xlsx, {}, []),
    'phyphox_zip': (f_phyphox_zip, {}, []),
    'tracker_xy': (f_tracker_xy, {}, []),
    'tracker_theta': (f_tracker_theta, dict(name='theta'), []),
    'tracker_theta_greek': (f_tracker_theta, dict(name='θ'), []),
    'vernier_deg': (f_vernier, dict(deg=True), []),
    'vernier_rad': (f_vernier, dict(deg=False), []),
    'pasco_rad': (f_pasco, dict(deg=False), []),
    'pasco_deg': (f_pasco, dict(deg=True), []),
    'pasco_2runs': (f_pasco, dict(deg=False, runs=2), []),
    'encoder_log': (f_encoder, {}, []),
    'encoder_events': (f_encoder_events, {}, []),
    'imu_list': (f_imu, {}, []),
}


def make(fmt, p, rng):
    fn, kw, args = FORMATS[fmt]
    dur = p['duration']
    if fmt == 'encoder_events':
        dur = min(dur, 30)  # one row per count: keep the file small
        p['duration'] = dur
    if fmt == 'encoder_log':
        p['rate'] = int(p['rate'])
    t, th, om = simulate(p['L'], p['Q'], p['amp'], p['rate'], dur, p['offset'], rng=rng)
    data, ext = fn(t, th, om, rng=rng, L=p['L'], rate=p['rate'], duration=dur, params=p, **kw)
    return data, ext, args, (t, th, om)


# ---------------------------------------------------------------- main
def main(seed=1):
    rng = random.Random(seed)
    if os.path.isdir(ROOT):
        shutil.rmtree(ROOT)

    # 1. well formed: each format x several random rigs
    per = 6
    for fmt in FORMATS:
        for i in range(per):
            p = rand_params(rng)
            data, ext, args, _ = make(fmt, p, rng)
            spp = (2 * math.pi * math.sqrt(p['L'] / G)) * p['rate']
            out('good', '%s_%02d.%s' % (fmt, i, ext), data, truth=p, good=True, fmt=fmt, args=args,
                note='samples/period %.1f' % spp)

    if os.environ.get('FUZZ_GOOD_ONLY'):
        json.dump(MAN, open(os.environ['FUZZ_MANIFEST'], 'w'), indent=1); print(len(MAN), 'good files'); return
    # 2. malformed variants, built on a comfortable base rig
    base = dict(L=0.5, Q=200.0, offset=0.03, amp=0.3, rate=50, duration=20)
    t, th, om = simulate(base['L'], base['Q'], base['amp'], base['rate'], base['duration'], base['offset'], rng=rng)
    H = ['t', 'theta']
    rows = [['%.4f' % a, '%.6f' % b] for a, b in zip(t, th)]

    def bad(name, data, note='', truth=None, args=None, fmt='plain_csv'):
        out('malformed', name, data, truth=truth, fmt=fmt, note=note, args=args)

    def csv(rs, header=H, **kw):
        return rows_text(header, rs, **kw)

    # emptiness
    bad('empty.csv', '')
    bad('whitespace.csv', '  \n\n \t\n')
    bad('header_only.csv', 't,theta\n')
    bad('header_only_noeol.csv', 't,theta')
    bad('header_only_vernier.csv', '"Latest: Time (s)","Latest: Angle (°)"\n', fmt='vernier')
    bad('header_only_pasco.txt', '\ufeffTime (s) Run #1\tAngle (rad) Run #1\r\n', fmt='pasco')
    bad('header_only_tracker.txt', 'mass_A\nt\tx\ty\n', fmt='tracker')
    bad('header_only_phyphox.csv', ','.join('"%s"' % h for h in PH_HDR) + '\n', fmt='phyphox')
    bad('encoder_header_only.txt', 'trigger_start_deg, sample_rate, duration_sec\n90, 1000, 5 \n', fmt='encoder')
    bad('encoder_first_line_only.txt', 'trigger_start_deg, sample_rate, duration_sec\n', fmt='encoder')
    bad('encoder_rate_zero.txt', 'trigger_start_deg, sample_rate, duration_sec\n90, 0, 5 \n' + '\n'.join('%.2f' % (b * 57.3) for b in th) + '\n', fmt='encoder')
    bad('encoder_rate_negative.txt', 'trigger_start_deg, sample_rate, duration_sec\n90, -50, 5 \n' + '\n'.join('%.2f' % (b * 57.3) for b in th) + '\n', fmt='encoder')
    bad('encoder_rate_nan.txt', 'trigger_start_deg, sample_rate, duration_sec\n90, nan, 5 \n' + '\n'.join('%.2f' % (b * 57.3) for b in th) + '\n', fmt='encoder')
    bad('encoder_rate_huge.txt', 'trigger_start_deg, sample_rate, duration_sec\n90, 1e300, 5 \n' + '\n'.join('%.2f' % (b * 57.3) for b in th) + '\n', fmt='encoder')
    bad('encoder_rate_tiny.txt', 'trigger_start_deg, sample_rate, duration_sec\n90, 1e-300, 5 \n' + '\n'.join('%.2f' % (b * 57.3) for b in th) + '\n', fmt='encoder')
    bad('encoder_text_line.txt', 'trigger_start_deg, sample_rate, duration_sec\n90, 50, 20 \n' + '\n'.join('%.2f' % (b * 57.3) if i != 300 else 'ERR' for i, b in enumerate(th)) + '\n', fmt='encoder')
    bad('encoder_nan_line.txt', 'trigger_start_deg, sample_rate, duration_sec\n90, 50, 20 \n' + '\n'.join('%.2f' % (b * 57.3) if i != 300 else 'nan' for i, b in enumerate(th)) + '\n', fmt='encoder')
    bad('one_row.csv', csv(rows[:1]))
    bad('two_rows.csv', csv(rows[:2]))
    bad('three_rows.csv', csv(rows[:3]))
    bad('ten_rows.csv', csv(rows[:10]))
    bad('one_row_vernier.csv', '"Latest: Time (s)","Latest: Angle (°)"\n"0.000","17.2"\n', fmt='vernier')
    bad('one_row_pasco.txt', '\ufeffTime (s) Run #1\tAngle (rad) Run #1\r\n0\t0,3\r\n', fmt='pasco')
    bad('one_row_tracker_xy.txt', 'mass_A\nt\tx\ty\n0.0\t700\t500\n', fmt='tracker')
    bad('two_rows_tracker_xy.txt', 'mass_A\nt\tx\ty\n0.0\t700\t500\n0.0166\t701\t500\n', fmt='tracker')
    bad('one_row_phyphox.csv', ','.join('"%s"' % h for h in PH_HDR) + '\n0.000000000E0,1.0E-2,2.0E-2,3.0E-1,3.0E-1\n', fmt='phyphox')

    # NaN / inf
    bad('all_nan_angle.csv', csv([[r[0], 'NaN'] for r in rows]))
    bad('all_nan_time.csv', csv([['NaN', r[1]] for r in rows]))
    bad('all_empty_angle.csv', csv([[r[0], ''] for r in rows]))
    bad('nan_middle.csv', csv([r if i != 500 else [r[0], 'NaN'] for i, r in enumerate(rows)]), truth=base)
    bad('nan_block_middle.csv', csv([r if not 400 <= i < 450 else [r[0], 'NaN'] for i, r in enumerate(rows)]), truth=base)
    bad('inf_middle.csv', csv([r if i != 500 else [r[0], 'inf'] for i, r in enumerate(rows)]), truth=base)
    bad('neg_inf_middle.csv', csv([r if i != 500 else [r[0], '-inf'] for i, r in enumerate(rows)]), truth=base)
    bad('Infinity_middle.csv', csv([r if i != 500 else [r[0], 'Infinity'] for i, r in enumerate(rows)]), truth=base)
    bad('nan_time_middle.csv', csv([r if i != 500 else ['NaN', r[1]] for i, r in enumerate(rows)]), truth=base)
    bad('inf_time_middle.csv', csv([r if i != 500 else ['inf', r[1]] for i, r in enumerate(rows)]), truth=base)
    bad('inf_time_last.csv', csv(rows + [['inf', '0.1']]), truth=base)
    bad('nan_first_row.csv', csv([['NaN', 'NaN']] + rows), truth=base)
    bad('nan_rate_col.csv', csv([[r[0], r[1], 'NaN'] for r in rows], header=['t', 'theta', 'theta_dot']), truth=base)
    bad('inf_rate_middle.csv', csv([[r[0], r[1], '%.5f' % w if i != 500 else 'inf'] for i, (r, w) in enumerate(zip(rows, om))], header=['t', 'theta', 'theta_dot']), truth=base)
    bad('vernier_nan_tail.csv', f_vernier(t, th, om)[0] + '"20.020",,\n' * 200, fmt='vernier', truth=base)
    pv = f_pasco(t, th, om, rng=rng)[0].split('\r\n')
    pv[600] = pv[600].split('\t')[0] + '\tNaN\tNaN'
    bad('pasco_nan_middle.txt', '\r\n'.join(pv), fmt='pasco', truth=base)
    gy = f_phyphox(t, th, om, rng=rng)[0].split('\n')
    gy[500] = '5.000000000E0,NaN,NaN,NaN,NaN'
    bad('phyphox_nan_middle.csv', '\n'.join(gy), fmt='phyphox', truth=base)
    gy = f_phyphox(t, th, om, rng=rng)[0].split('\n')
    gy[500] = '1.000000000E1,1.0E-2,inf,1.0E-2,inf'
    bad('phyphox_inf_middle.csv', '\n'.join(gy), fmt='phyphox', truth=base)
    gy = f_phyphox(t, th, om, rng=rng)[0].split('\n')
    bad('phyphox_all_nan_gyro.csv', '\n'.join([gy[0]] + ['%s,NaN,NaN,NaN,NaN' % l.split(',')[0] for l in gy[1:] if l]) + '\n', fmt='phyphox')

    # text in a numeric cell
    bad('text_cell.csv', csv([r if i != 500 else [r[0], 'abc'] for i, r in enumerate(rows)]))
    bad('text_time_cell.csv', csv([r if i != 500 else ['12:00:01', r[1]] for i, r in enumerate(rows)]))
    bad('text_cell_first_row.csv', csv([['0.0', 'start']] + rows[1:]))
    bad('text_unit_row.csv', csv([['s', 'rad']] + rows), note='a units row under the header')
    bad('text_cell_tracker.txt', f_tracker_xy(t, th, om, L=0.5, rng=rng)[0].replace('\n', '\nXX\tyy\tzz\n', 500).replace('\nXX\tyy\tzz\n', '\n', 499), fmt='tracker')
    bad('thousands_sep.csv', csv([[r[0], r[1]] for r in rows], header=['t', 'theta']).replace('0.0', '0,0', 5), note='comma in numbers of a comma file')

    # ragged
    bad('ragged_short_row.csv', csv([r if i != 500 else [r[0]] for i, r in enumerate(rows)]))
    bad('ragged_long_row.csv', csv([r if i != 500 else r + ['1', '2'] for i, r in enumerate(rows)]))
    bad('ragged_every_other.csv', csv([r if i % 2 else r + ['9'] for i, r in enumerate(rows)]))
    bad('ragged_header_longer.csv', csv(rows, header=['t', 'theta', 'omega']))
    bad('ragged_header_shorter.csv', csv([r + ['0.5'] for r in rows], header=['t', 'theta']))
    bad('trailing_sep.csv', csv([r + [''] for r in rows], header=['t', 'theta', '']), truth=base, note='Excel trailing comma')
    bad('blank_lines_between.csv', csv(rows).replace('\n', '\n\n'), truth=base)

    # time stamps
    dup = []
    for i, r in enumerate(rows):
        dup.append(r)
        if i % 100 == 50:
            dup.append(r)
    bad('dup_time_rows.csv', csv(dup), truth=base)
    bad('dup_time_diff_value.csv', csv([r if i != 501 else [rows[500][0], r[1]] for i, r in enumerate(rows)]), truth=base)
    bad('dup_time_all.csv', csv([[rows[0][0], r[1]] for r in rows]))
    bad('dup_every_row.csv', csv([r for r in rows for _ in (0, 1)]), truth=base)
    bad('time_quantized_tracker.csv', csv([['%.1f' % float(r[0]), r[1]] for r in rows]), note='time rounded to 0.1 s at 50 Hz', truth=base)
    bad('decreasing_one.csv', csv([rows[i] if i not in (500, 501) else rows[1001 - i] for i in range(len(rows))]))
    bad('decreasing_all.csv', csv(rows[::-1]))
    bad('time_resets.csv', csv(rows + [['%.4f' % (float(r[0])), r[1]] for r in rows]), note='logger restarted clock')
    bad('huge_gap.csv', csv(rows[:500] + [['%.4f' % (float(r[0]) + 1000), r[1]] for r in rows[500:]]), truth=base)
    bad('huge_gap_1e9.csv', csv(rows[:500] + [['%.4f' % (float(r[0]) + 1e9), r[1]] for r in rows[500:]]), truth=base)
    bad('gap_single_last.csv', csv(rows + [['1e6', rows[-1][1]]]), truth=base)
    bad('negative_time.csv', csv([['%.4f' % (float(r[0]) - 10), r[1]] for r in rows]), truth=base)
    bad('all_negative_time_decr.csv', csv([['%.4f' % (-float(r[0])), r[1]] for r in rows]))
    bad('epoch_time.csv', csv([['%.4f' % (float(r[0]) + 1.7e9), r[1]] for r in rows]), truth=base, note='Unix seconds')
    bad('epoch_ms_time.csv', csv([['%d' % round((float(r[0]) + 1.7e9) * 1000), r[1]] for r in rows], header=['timestamp', 'theta']), note='Unix ms under a default name')
    bad('time_ms.csv', csv([['%.1f' % (float(r[0]) * 1000), r[1]] for r in rows], header=['time (ms)', 'theta']), truth=base)
    bad('time_zero_all.csv', csv([['0', r[1]] for r in rows]))
    bad('uneven_jitter.csv', csv([['%.5f' % a, '%.6f' % b] for a, b in zip(*simulate(0.5, 200, 0.3, 50, 20, 0.03, rng=rng, jitter=0.45)[:2])]), truth=base)
    bad('tiny_dt.csv', csv([['%.12f' % (k * 1e-9), r[1]] for k, r in enumerate(rows)]), note='1 ns steps')

    # constant / mislabelled / huge
    bad('constant_angle.csv', csv([[r[0], '0.0300'] for r in rows]))
    bad('constant_angle_noise.csv', csv([[r[0], '%.6f' % (0.03 + rng.gauss(0, 0.001))] for r in rows]))
    bad('constant_vernier_deg.csv', f_vernier(t, [0.03] * len(t), [0.0] * len(t))[0], fmt='vernier')
    bad('constant_tracker_xy.txt', 'mass_A\nt\tx\ty\n' + ''.join('%r\t700.0\t500.0\n' % a for a in t), fmt='tracker')
    bad('constant_gyro_zero.csv', rows_text(PH_HDR, [[E(a), E(0.0), E(0.0), E(0.0), E(0.0)] for a in t], quote=True), fmt='phyphox')
    bad('gyro_bias_only.csv', rows_text(PH_HDR, [[E(a), E(0.001), E(0.002), E(0.05), E(0.05)] for a in t], quote=True), fmt='phyphox')
    bad('deg_labelled_rad.csv', csv([[r[0], '%.4f' % (b * 180 / math.pi)] for r, b in zip(rows, th)], header=['t', 'theta (rad)']), truth=base)
    bad('deg_no_label.csv', csv([[r[0], '%.4f' % (b * 180 / math.pi)] for r, b in zip(rows, th)]), truth=base)
    bad('vernier_deg_labelled_rad.csv', f_vernier(t, th, om, deg=True)[0].replace('°', 'rad'), truth=base, fmt='vernier')
    bad('rad_labelled_deg.csv', csv(rows, header=['t', 'theta (deg)']), truth=base)
    bad('small_deg_labelled_rad.csv', csv([[r[0], '%.4f' % (b * 180 / math.pi * 0.1)] for r, b in zip(rows, th)], header=['t', 'theta (rad)']), truth=base, note='3 deg swing in degrees labelled rad')
    bad('value_1e30_one.csv', csv([r if i != 500 else [r[0], '1e30'] for i, r in enumerate(rows)]), truth=base)
    bad('value_1e30_all.csv', csv([[r[0], '%.6e' % (float(r[1]) * 1e30)] for r in rows]))
    bad('value_1e308_one.csv', csv([r if i != 500 else [r[0], '1.7e308'] for i, r in enumerate(rows)]), truth=base)
    bad('value_1e309_one.csv', csv([r if i != 500 else [r[0], '1e309'] for i, r in enumerate(rows)]), truth=base)
    bad('value_tiny_all.csv', csv([[r[0], '%.6e' % (float(r[1]) * 1e-30)] for r in rows]))
    bad('time_1e30.csv', csv([['%.6e' % (float(r[0]) * 1e30 + 1e30), r[1]] for r in rows]))
    bad('time_1e300_step.csv', csv([['%.6e' % (k * 1e300), r[1]] for k, r in enumerate(rows)]))
    bad('gyro_1e30.csv', rows_text(PH_HDR, [[E(a), E(1e30), E(1e30), E(1e30), E(1e30)] for a in t], quote=True), fmt='phyphox')
    bad('tracker_xy_1e30.txt', 'mass_A\nt\tx\ty\n' + ''.join('%r\t%r\t%r\n' % (a, 1e30 * math.sin(b), -1e30 * math.cos(b)) for a, b in zip(t, th)), fmt='tracker')
    bad('tracker_xy_huge_offset.txt', 'mass_A\nt\tx\ty\n' + ''.join('%r\t%r\t%r\n' % (a, 1e12 + 300 * math.sin(b), 1e12 - 300 * math.cos(b)) for a, b in zip(t, th)), fmt='tracker', truth=base)
    bad('tracker_xy_collinear.txt', 'mass_A\nt\tx\ty\n' + ''.join('%r\t%r\t500.0\n' % (a, 700 + 300 * b) for a, b in zip(t, th)), fmt='tracker', note='x moves, y flat: no arc')
    bad('tracker_xy_missing_frames.txt', 'mass_A\nt\tx\ty\n' + ''.join(('%r\t%r\t%r\n' % (a, 640 + 300 * math.sin(b), 900 - 300 * math.cos(b))) if i % 7 else '%r\t\t\n' % a for i, (a, b) in enumerate(zip(t, th))), fmt='tracker', truth=base)

    # line endings / encodings
    body = csv(rows)
    mixed = ''.join(l + ['\n', '\r\n', '\r'][i % 3] for i, l in enumerate(body.split('\n')[:-1]))
    bad('mixed_eol.csv', mixed, truth=base)
    bad('cr_only.csv', body.replace('\n', '\r'), truth=base, note='old Mac line ends')
    bad('crlf.csv', body.replace('\n', '\r\n'), truth=base)
    bad('bom_semicolon.csv', '\ufeff' + body.replace(',', ';'), truth=base)
    bad('bom_semicolon_deccomma.csv', '\ufeff' + body.replace(',', ';').replace('.', ','), truth=base)
    bad('bom_semicolon_quoted_deccomma.csv', '\ufeff' + rows_text(['Time (s)', 'Angle (rad)'], rows, sep=';', decimal_comma=True, quote=False), truth=base)
    bad('double_bom.csv', '\ufeff\ufeff' + body, truth=base)
    bad('utf16le_bom.csv', '\ufeff'.encode('utf-16-le') + rows_text(['Time (s)', 'Angle (rad)'], rows, sep='\t', eol='\r\n').encode('utf-16-le'), truth=base, note='Excel "Unicode text"')
    bad('latin1_degree.csv', rows_text(['Time (s)', 'Angle (°)'], [[r[0], '%.4f' % (b * 57.29578)] for r, b in zip(rows, th)]).encode('latin-1'), truth=base, note='cp1252 ° in the header')
    bad('nul_bytes.csv', body.replace('\n', '\x00\n', 20))
    bad('nul_cell.csv', csv([r if i != 500 else [r[0], '\x00'] for i, r in enumerate(rows)]))
    bad('quoted_cells_comma.csv', rows_text(['t', 'theta'], [['"%s"' % a, '"%s"' % b] for a, b in rows]), truth=base)
    bad('unterminated_quote.csv', csv(rows).replace('\n0.5000', '\n"0.5000', 1))

    # unknown headers
    bad('unknown_headers.csv', csv(rows, header=['foo', 'bar']))
    bad('unknown_headers_4col.csv', csv([r + ['1', '2'] for r in rows], header=['a', 'b', 'c', 'd']))
    bad('no_header.csv', csv(rows, header=None), note='numbers from line 1')
    bad('unknown_with_time_col_opt.csv', csv(rows, header=['foo', 'bar']), args=['--time-column', '1', '--angle-column', '2'], truth=base)
    bad('bad_time_col_opt.csv', csv(rows), args=['--time-column', '9'])
    bad('bad_time_col_zero.csv', csv(rows), args=['--time-column', '0'])
    bad('same_col_time_angle.csv', csv(rows), args=['--time-column', '1', '--angle-column', '1'])
    bad('angle_col_name_missing.csv', csv(rows), args=['--angle-column', 'phi'])
    bad('dup_header_names.csv', csv([r + [r[1]] for r in rows], header=['t', 'theta', 'theta']))
    bad('header_only_time.csv', csv([[r[0]] for r in rows], header=['t']))
    bad('header_many_cols.csv', csv([r + ['0'] * 5000 for r in rows[:200]], header=H + ['c%d' % i for i in range(5000)]))
    bad('rate_no_time.csv', csv([[r[1]] for r in rows], header=['theta']), args=['--rate', '50'], truth=base)
    bad('rate_no_time_zero.csv', csv([[r[1]] for r in rows], header=['theta']), args=['--rate', '0'])
    bad('rate_no_time_neg.csv', csv([[r[1]] for r in rows], header=['theta']), args=['--rate', '-5'])
    bad('rate_no_time_nan.csv', csv([[r[1]] for r in rows], header=['theta']), args=['--rate', 'NaN'])
    bad('rate_no_time_inf.csv', csv([[r[1]] for r in rows], header=['theta']), args=['--rate', 'inf'])
    bad('rate_no_time_1e-300.csv', csv([[r[1]] for r in rows], header=['theta']), args=['--rate', '1e-300'])
    bad('rate_no_time_1e300.csv', csv([[r[1]] for r in rows], header=['theta']), args=['--rate', '1e300'])
    bad('opt_dt_zero.csv', csv(rows), args=['--dt', '0'])
    bad('opt_dt_neg.csv', csv(rows), args=['--dt', '-0.04'])
    bad('opt_dt_nan.csv', csv(rows), args=['--dt', 'NaN'])
    bad('opt_dt_tiny.csv', csv(rows), args=['--dt', '1e-9'])
    bad('opt_dt_huge.csv', csv(rows), args=['--dt', '1e9'])
    bad('opt_smooth_zero.csv', csv(rows), args=['--smooth', '0'], truth=base)
    bad('opt_smooth_nan.csv', csv(rows), args=['--smooth', 'NaN'])
    bad('opt_smooth_huge.csv', csv(rows), args=['--smooth', '1e9'])
    bad('opt_start_past_end.csv', csv(rows), args=['--start', '1000'])
    bad('opt_start_nan.csv', csv(rows), args=['--start', 'NaN'])
    bad('opt_duration_zero.csv', csv(rows), args=['--duration', '0'])
    bad('opt_duration_neg.csv', csv(rows), args=['--duration', '-1'])
    bad('opt_pivot_nan.txt', f_tracker_xy(t, th, om, L=0.5, rng=rng)[0], args=['--pivot', 'NaN,NaN'], fmt='tracker')
    bad('opt_pivot_on_bob.txt', 'mass_A\nt\tx\ty\n' + ''.join('%r\t%r\t%r\n' % (a, 640 + 300 * math.sin(b), 900 - 300 * math.cos(b)) for a, b in zip(t, th)), args=['--pivot', '640,600'], fmt='tracker')

    # binary / archives
    bad('garbage.csv', bytes(rng.getrandbits(8) for _ in range(20000)))
    bad('garbage.txt', bytes(rng.getrandbits(8) for _ in range(200)))
    bad('garbage.xlsx', bytes(rng.getrandbits(8) for _ in range(5000)), fmt='xlsx')
    bad('garbage.zip', b'PK\x03\x04' + bytes(rng.getrandbits(8) for _ in range(5000)), fmt='zip')
    bad('png_as_csv.csv', b'\x89PNG\r\n\x1a\n' + bytes(rng.getrandbits(8) for _ in range(3000)))
    good_x = f_phyphox_xlsx(t, th, om, rng=rng)[0]
    for frac in (0.1, 0.5, 0.9, 0.99):
        bad('truncated_%02d.xlsx' % int(frac * 100), good_x[:int(len(good_x) * frac)], fmt='xlsx')
    bad('zero_byte.xlsx', b'', fmt='xlsx')
    flipped = bytearray(good_x)
    for k in range(200, len(flipped), 997):
        flipped[k] ^= 0x5A
    bad('bitflip.xlsx', bytes(flipped), fmt='xlsx')
    bad('xlsx_named_csv.csv', good_x, fmt='xlsx', truth=base, note='an xlsx saved with a .csv name')
    bad('csv_named_xlsx.xlsx', body, fmt='xlsx', truth=base, note='a CSV saved with an .xlsx name')
    bad('xlsx_empty_sheet.xlsx', xlsx_bytes([('Gyroscope', None, [])]), fmt='xlsx')
    bad('xlsx_header_only.xlsx', xlsx_bytes([('Gyroscope', PH_HDR, [])]), fmt='xlsx')
    bad('xlsx_angle_one_row.xlsx', xlsx_bytes([('Data', ['Time (s)', 'Angle (rad)'], [[0.0, 0.3]])]), fmt='xlsx')
    bad('xlsx_error_cells.xlsx', xlsx_bytes([('Data', ['Time (s)', 'Angle (rad)'], [[a, b] if i != 500 else [a, '#DIV/0!'] for i, (a, b) in enumerate(zip(t, th))])]), fmt='xlsx', truth=base)
    bad('xlsx_text_numbers.xlsx', xlsx_bytes([('Data', ['Time (s)', 'Angle (rad)'], [[dc('%.4f' % a), dc('%.6f' % b)] for a, b in zip(t, th)])]), fmt='xlsx', truth=base, note='numbers stored as text with decimal comma')
    bad('xlsx_gaps_cells.xlsx', xlsx_bytes([('Data', ['Time (s)', 'Angle (rad)'], [[a, b] if i % 9 else [a, None] for i, (a, b) in enumerate(zip(t, th))])]), fmt='xlsx', truth=base)
    bad('xlsx_angle_sheet.xlsx', xlsx_bytes([('Data', ['Time (s)', 'Angle (rad)'], [[a, b] for a, b in zip(t, th)])]), fmt='xlsx', truth=base)
    bad('xlsx_nan_time.xlsx', xlsx_bytes([('Data', ['Time (s)', 'Angle (rad)'], [[a, b] if i != 300 else ['nan', b] for i, (a, b) in enumerate(zip(t, th))])]), fmt='xlsx')
    zb = io.BytesIO(); z = zipfile.ZipFile(zb, 'w'); z.writestr('meta/device.csv', '"a","b"\n'); z.close()
    bad('zip_meta_only.zip', zb.getvalue(), fmt='zip')
    zb = io.BytesIO(); z = zipfile.ZipFile(zb, 'w'); z.close()
    bad('zip_empty.zip', zb.getvalue(), fmt='zip')
    zb = io.BytesIO(); z = zipfile.ZipFile(zb, 'w', zipfile.ZIP_DEFLATED); z.writestr('Gyroscope.csv', '\0' * 50_000_000); z.close()
    bad('zip_bomb_50MB_nul.zip', zb.getvalue(), fmt='zip', note='50 MB of NUL compressed')
    zb = io.BytesIO(); z = zipfile.ZipFile(zb, 'w', zipfile.ZIP_BZIP2); z.writestr('Gyroscope.csv', f_phyphox(t, th, om, rng=rng)[0]); z.close()
    bad('zip_bzip2.zip', zb.getvalue(), fmt='zip', note='bzip2 member (doc: deflate only)')
    zb = io.BytesIO(); z = zipfile.ZipFile(zb, 'w', zipfile.ZIP_DEFLATED); z.writestr('inner.zip', good_x); z.close()
    bad('zip_nested.zip', zb.getvalue(), fmt='zip')
    zb = io.BytesIO(); z = zipfile.ZipFile(zb, 'w', zipfile.ZIP_DEFLATED); z.writestr('../../evil.csv', body); z.close()
    bad('zip_path_traversal.zip', zb.getvalue(), fmt='zip', truth=base)
    zfull = f_phyphox_zip(t, th, om, rng=rng)[0]
    bad('zip_truncated.zip', zfull[:len(zfull) // 2], fmt='zip')

    # very long lines
    bad('long_line_number.csv', csv(rows[:500] + [[rows[500][0], '0.' + '1' * 5_000_000]] + rows[501:]), truth=base)
    bad('long_line_text.csv', csv(rows[:500] + [[rows[500][0], 'x' * 5_000_000]] + rows[501:]))
    bad('long_header.csv', 't,' + 'theta' + 'a' * 3_000_000 + '\n' + csv(rows, header=None))
    bad('long_line_no_newline.csv', '1' * 20_000_000)
    bad('long_preamble.csv', ('# comment line\n' * 200000) + body, truth=base)
    bad('many_rows_10M.csv', 't,theta\n' + ''.join('%d,%.3f\n' % (k, 0.3 * math.cos(k * 0.5)) for k in range(0, 3_000_000)), note='3 M rows at 1 Hz-ish stamps')
    bad('long_line_commas.csv', csv(rows[:500] + [[rows[500][0], rows[500][1]] + [''] * 1_000_000] + rows[501:]))

    # 3. near-miss good files (realistic variations a user expects to work)
    def near(name, data, p, note='', args=None, fmt=''):
        out('nearmiss', name, data, truth=p, good=True, fmt=fmt, note=note, args=args)
    for i in range(6):
        p = rand_params(rng)
        tt, a, w = simulate(p['L'], p['Q'], p['amp'], p['rate'], p['duration'], p['offset'], rng=rng, jitter=0.3)
        near('plain_jitter_%02d.csv' % i, f_plain(tt, a, w)[0], p, note='stamps jittered 30%', fmt='plain_csv')
    p = dict(base); tt, a, w = simulate(p['L'], p['Q'], p['amp'], p['rate'], p['duration'], p['offset'], rng=rng)
    near('plain_with_rate_col.csv', rows_text(['t', 'theta', 'omega'], [(x, y, z) for x, y, z in zip(tt, a, w)]), p, fmt='plain_csv')
    near('plain_time_s_angle_deg.csv', rows_text(['time_s', 'angle (deg)'], [(x, y * 57.29577951308232) for x, y in zip(tt, a)]), p, fmt='plain_csv')
    near('plain_Time_Angle_caps.csv', rows_text(['Time', 'Angle'], [(x, y) for x, y in zip(tt, a)]), p, fmt='plain_csv')
    near('plain_tab.tsv', rows_text(['t', 'theta'], [(x, y) for x, y in zip(tt, a)], sep='\t'), p, fmt='plain_csv')
    near('plain_spaces.txt', rows_text(['t', 'theta'], [(x, y) for x, y in zip(tt, a)], sep=' '), p, fmt='plain_csv', note='space separated')
    near('plain_comment_preamble.csv', '# recorded 2024-05-01\n# rig B\n' + rows_text(['t', 'theta'], [(x, y) for x, y in zip(tt, a)]), p, fmt='plain_csv')
    near('vernier_two_runs.csv', rows_text(['Run 1: Time (s)', 'Run 1: Angle (°)', 'Run 2: Time (s)', 'Run 2: Angle (°)'],
                                            [('%.3f' % x, '%.3f' % (y * 57.2958), '%.3f' % x, '%.3f' % (y * 0.9 * 57.2958)) for x, y in zip(tt, a)], quote=True), p, fmt='vernier')
    near('vernier_rad_integer_time_ms.csv', f_vernier(tt, a, w, deg=False)[0], p, fmt='vernier')
    near('pasco_rad_lf_only.txt', f_pasco(tt, a, w, rng=rng)[0].replace('\r\n', '\n'), p, fmt='pasco')
    near('pasco_no_bom.txt', f_pasco(tt, a, w, rng=rng)[0].lstrip('\ufeff'), p, fmt='pasco')
    near('pasco_3runs.txt', f_pasco(tt, a, w, rng=rng, runs=3, params=p)[0], p, fmt='pasco')
    near('tracker_xy_y_down.txt', 'mass_A\n' + rows_text(['t', 'x', 'y'], [(E(x), E(640 + 300 * math.sin(y)), E(200 + 300 * math.cos(y))) for x, y in zip(tt, a)], sep='\t'), p, fmt='tracker', note='image y down, pivot (640,200)')
    near('tracker_xy_pivot_origin_m.txt', 'mass_A\n' + rows_text(['t', 'x', 'y'], [(E(x), E(0.5 * math.sin(y)), E(-0.5 * math.cos(y))) for x, y in zip(tt, a)], sep='\t'), p, fmt='tracker', note='metres, pivot at origin')
    near('tracker_two_tracks.txt', 'mass_A\n' + rows_text(['t', 'x', 'y', 'x', 'y'], [(E(x), E(640 + 300 * math.sin(y)), E(900 - 300 * math.cos(y)), E(640.0), E(900.0)) for x, y in zip(tt, a)], sep='\t'), p, fmt='tracker', note='bob and pivot tracked')
    near('phyphox_gyro_y_axis.csv', rows_text(PH_HDR, [[E(x), E(0.02 * z), E(z + 0.01), E(0.01 * z), E(abs(z))] for x, z in zip(tt, w)], quote=True), p, fmt='phyphox')
    near('phyphox_gyro_diag_axis.csv', rows_text(PH_HDR, [[E(x), E(0.7071 * z), E(0.7071 * z), E(0.0), E(abs(z))] for x, z in zip(tt, w)], quote=True), p, fmt='phyphox', note='swing axis between x and y')
    near('encoder_events_ticks.csv', rows_text(['time (s)', 'count'], [('%.6f' % x, str(c)) for x, c in encoder_events(tt, a)[0]]), p, fmt='encoder_events', note='counts not degrees; user names nothing', args=[])
    ev = encoder_events(tt, a)[0]
    near('encoder_events_us.csv', rows_text(['timestamp_us', 'angle_deg'], [('%d' % round(x * 1e6), '%.3f' % (c * 0.09)) for x, c in ev]), p, fmt='encoder_events', note='us stamps', args=['--time-column', '1', '--angle-column', '2', '--unit', 'degrees'])
    near('encoder_events_dup_stamps.csv', rows_text(['t', 'angle (deg)'], [('%.3f' % x, '%.2f' % (c * 0.09)) for x, c in ev]), p, fmt='encoder_events', note='ms resolution: many equal stamps with different counts')
    p2 = dict(base, rate=1000, duration=10)
    tt2, a2, w2 = simulate(p2['L'], p2['Q'], 1.2, 1000, 10, p2['offset'], rng=rng, noise=0.0)
    near('encoder_log_1khz_large_swing.txt', f_encoder(tt2, a2, w2, rate=1000, duration=10)[0], dict(p2, amp=1.2), fmt='encoder_log')

    with open(os.environ['FUZZ_MANIFEST'], 'w') as fh:
        json.dump(MAN, fh, indent=1)
    cats = {}
    for m in MAN:
        cats[m['category']] = cats.get(m['category'], 0) + 1
    print(len(MAN), 'files', cats)


if __name__ == '__main__':
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 1)
